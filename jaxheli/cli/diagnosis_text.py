"""The diagnosis on the console: the ranking table and the verdict's line, worded from the typed records
(:class:`~jaxheli.gap.records.Diagnosis`, :class:`~jaxheli.gap.verdict.Verdict`); the advice that names commands and
options is worded here, not in the library."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..gap.ranking import RECHECK
from ..gap.records import Diagnosis, Entry
from ..gap.verdict import Verdict, still_converging, under_fitted


def verdict_line(verdict: Verdict) -> str:
    """``verdict`` in words (its sentence, :func:`~jaxheli.gap.verdict.sentence`), but while the re-fitted base is
    still converging: then what to run before attributing effects."""
    refit = verdict.under_fitted
    if refit is None or refit.settled:
        return str(verdict)
    return (f"{under_fitted(refit)} and {still_converging(refit)}: re-identify the base model (jaxheli identify "
            f"--method pem --data FILE, or the diagnosis's re-fitted base, refit.theta), or raise max_steps "
            f"(--max-steps), before attributing effects")


def ranking_table(diagnosis: Diagnosis) -> list[str]:
    """The base model's gap on the validation flight (nmse, total and per channel), then a table of shrinks of
    that gap (%): the base model re-fitted alone when the diagnosis re-identified jointly (its shrink of the given
    base; ``U``: under-fitted), its re-fit in the physical ranges (shrink of the better model without an effect;
    ``S``: significant, the effects below are then ranked beyond it), and the ranked effects (total with its
    standard error and per channel; ``*`` significant, ``=`` tied with another), and those re-checked beyond the
    structure (:func:`jaxheli.gap.ranking.staged`)."""
    names, before, found = diagnosis.outputs, diagnosis.gap_before, diagnosis.attribution
    lines = [f"  base model's validation gap (nmse): total {before.total:.3g}; "
             + ", ".join(f"{n} {before.channel[n]:.3g}" for n in names),
             f"  {'shrink of that gap':<22}{'%':>9}{'+-':>6}  {'sig':<4}" + "".join(f"{n:>8}" for n in names)
             + "  fitted"]
    refit, structure = found.base_refit, found.structure
    if refit is not None:
        lines.append(_row("(base re-fitted)", refit.shrink_pct, refit.shrink_se_pct, "U" if refit.under_fitted else "",
                          [_pct(before.channel[n], refit.gap_by_channel[n]) for n in names],
                          "effects below: shrink beyond this"))
    if structure is not None:
        lines.append(_row("(base, physical box)", structure.shrink_pct, structure.shrink_se_pct,
                          "S" if structure.significant else "",
                          [_pct(before.channel[n], structure.gap_by_channel[n]) for n in names], structure.summary))
    for e in (*found.ranking, *found.shown[1:]):
        mark = ("=" if e.tied_with else "*") if e.significant else ""
        lines.append(_row(e.effect, e.shrink_pct, e.shrink_se_pct, mark, [e.shrink_by_channel[n] for n in names],
                          e.fitted.summary))
    if found.recheck:
        rule = "where it is significant here" if RECHECK == "all" else "only if here too"
        lines.append(f"  re-checked beyond the structure, in the physical ranges (significant above {rule}):")
        lines += [_entry_row(e, names) for e in found.recheck]
    if found.beyond_noise:
        lines.append("  re-checked beyond process noise, its gusts freed in every fit (one significant here, its "
                     "likelihood-ratio p within the threshold too, is named in its place):")
        lines += [_entry_row(e, names) for e in found.beyond_noise]
    for rival, e in found.noise_beyond.items():
        lines.append(f"  process noise re-checked beyond {rival} (named in its place if not significant here):")
        lines.append(_entry_row(e, names))
    return lines


def _entry_row(e: Entry, names: Sequence[str]) -> str:
    """A line of :func:`ranking_table` for a re-checked entry: significant (``*``) or not."""
    return _row(e.effect, e.shrink_pct, e.shrink_se_pct, "*" if e.significant else "",
                [e.shrink_by_channel[n] for n in names], e.fitted.summary)


def _row(label: str, shrink: float, se: float, mark: str, channels: Sequence[float], note: str) -> str:
    """A line of :func:`ranking_table`."""
    return (f"  {label:<22}{_num(shrink, '.1f'):>9}{_num(se, '.1f'):>6}  {mark:<4}"
            + "".join(f"{_num(c, '.1f'):>8}" for c in channels) + f"  {note}")


def _pct(before: float, after: float) -> float:
    return float("nan") if before == 0 else 100.0 * (before - after) / before


def _num(value: float, fmt: str) -> str:
    """``value`` formatted, in two significant digits from 1e5 on (a diverged candidate's shrink of -1e160 %), or
    ``-`` where it is not finite (``null`` in ``diagnosis.json``)."""
    if not np.isfinite(value):
        return "-"
    return format(value, fmt) if abs(value) < 1e5 else format(value, ".2g")
