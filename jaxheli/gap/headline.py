"""The diagnosis's first line, in words: the significant data-consistency findings of either flight first (a rate
scale, a time base: they bias every fit after them), then what was found (the effect with its size and its shrink
of the validation gap, then the base model's own shortfalls), and, when nothing in the catalogue explains a gap that
the sticks still explain, where that gap lies (channel, band, lag). The parameter lists stay below it, in the
verdict's sentence (:func:`~jaxheli.gap.verdict.sentence`) and the ranking."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from .correction import CORRECTED
from .localisation_record import Summary
from .verdict import Verdict

NO_EFFECT = "no significant effect"
"""The headline's words when nothing is found and the base model's gap is not explained by the sticks."""


def headline(verdict: Verdict, consistency: Sequence[Mapping[str, Any]], where: Summary) -> str:
    """One line: ``consistency``'s significant findings of the kinds the correction applies (JSON, with their
    ``flight``; :data:`~jaxheli.gap.correction.CORRECTED`: a time base, a gyro scale or lag, a bias, a frame), named
    per flight (:func:`defects`; their numbers are in ``consistency.json``), then :func:`found`. Those that only ask
    for a look (a velocity's lag or drift) stay in ``consistency.json``."""
    return "; ".join([*defects(consistency), found(verdict, where)])


_SCALES = ("time_scale", "rate_scale", "velocity_scale")
"""Kinds whose estimate is a dimensionless scale factor, shown in the headline."""


def defects(consistency: Sequence[Mapping[str, Any]]) -> list[str]:
    """``["train flight data: time scale x1.246, attitude bias of phi", ...]``: per flight, the significant findings
    the correction applies, by kind and channels, a scale factor with its value."""
    named: dict[str, list[str]] = {}
    for f in consistency:
        if f.get("significant") and f.get("kind") in CORRECTED:
            what = f["kind"].replace("_", " ")
            est = f.get("estimate")
            if f["kind"] in _SCALES and isinstance(est, (int, float)):
                what += f" x{est:.3g}"
            channels = [c for c in f.get("channels", ()) if c != "time"]
            named.setdefault(f["flight"], []).append(what + (f" of {','.join(channels)}" if channels else ""))
    return [f"{flight} flight data: {', '.join(kinds)}" for flight, kinds in named.items()]


def found(verdict: Verdict, where: Summary) -> str:
    """What ``verdict`` found, in words and percentages: the effect (its fitted size, its shrink of the validation
    gap, beyond process noise when named in its place, else beyond the structure when the structure is named), then
    the base model's structure and under-fit with their shrinks; with no effect, where the base model's gap lies
    (``where``, the localisation's summary) when the sticks explain it (:func:`unexplained`), else
    :data:`NO_EFFECT`."""
    refit = verdict.under_fitted
    if refit is not None and not refit.settled:
        return (f"the base model is still converging (training RSS down {refit.progress_pct:.1f} % over its last "
                f"{refit.steps} steps): no effect attributed")
    parts = []
    e = verdict.effect
    if e is not None:
        tie = f" (tied with {' and '.join(verdict.tied_with)})" if verdict.tied_with else ""
        beyond = " beyond the base model's structure" if verdict.structure is not None else ""
        if verdict.noise is not None:
            beyond = " beyond process noise" if verdict.noise_after is None else ""
        parts.append(f"{e.fitted.summary}{tie}: the validation gap shrinks {e.shrink_pct:.0f} %{beyond}")
    s = verdict.structure
    if s is not None:
        parts.append(f"the base model's structure: re-fitted in the physical ranges it shrinks the gap "
                     f"{s.shrink_pct:.0f} %")
    if refit is not None:
        parts.append(f"the base model under-fitted: re-fitted alone it shrinks the gap {refit.shrink_pct:.0f} %")
    if e is None:
        parts.append(unexplained(where, rest=bool(parts)) if explained_by_sticks(where) else NO_EFFECT)
    return "; ".join(parts)


def explained_by_sticks(where: Summary) -> bool:
    """The base model's gap is input-driven: its worst band's residual is coherent with the sticks
    (``"structure"``), or a stick-residual lag is significant."""
    return where.worst_band_verdict == "structure" or where.strongest_lag.significant


def unexplained(where: Summary, rest: bool = False) -> str:
    """``"no catalogued effect explains the base model's gap, which lies in q at 0.5-2 Hz (64 % of its gap), q lagging
    lon by 40 ms"`` (``rest``: "the rest", after the base model's own shortfalls)."""
    lo, hi = where.worst_band_hz
    gap = "the rest" if rest else "the base model's gap"
    text = (f"no catalogued effect explains {gap}, which lies in {where.worst_channel} at {lo:g}-{hi:.3g} Hz "
            f"({100 * where.worst_band_share:.0f} % of its gap)")
    lag = where.strongest_lag
    if lag.significant:
        text += f", {lag.channel} lagging {lag.input} by {1000 * lag.peak_lag_s:.0f} ms"
    return text
