"""What the diagnosis found, as a record: the base model under-fitted, its structure named, the effect named (with
its shrink, size and standard errors), or nothing significant; and that record in a sentence.

The verdict is a pure function of the attribution's ranking, the base re-fitted alone, the structure hypothesis and
the re-check beyond it (:func:`find`). The sentence here (:func:`sentence`) is the one ``diagnosis.json`` holds; it
names no command-line option: the command line adds its own advice (``jaxheli.cli``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import TYPE_CHECKING

from .thresholds import THRESHOLDS

if TYPE_CHECKING:  # the rules read the records' fields only, so records.py can import this module
    from .candidate_records import Entry, Refit, Structure


@dataclasses.dataclass(frozen=True)
class Verdict:
    """What the diagnosis found (:func:`find`).

    Attributes:
        under_fitted: the base model re-fitted alone (:class:`~jaxheli.gap.candidate_records.Refit`) when it names
            the given base under-fitted: its held-out shrink passed the noise, or it is still converging (``settled``
            false: then nothing else is judged and ``structure`` and ``effect`` are ``None``); ``None`` otherwise.
        structure: the base model's structure, named before any effect: significant, and no significant effect
            shrinks the validation gap as far (:func:`structure_leads`); ``None`` otherwise.
        effect: the best significant effect's ranking entry (its shrink, standard error and fitted size), its entry
            of the re-check beyond the structure when the structure is named; ``None``: no significant effect.
        tied_with: the significant effects within the named effect's noise.
        outshrinks: the significant structure the named effect shrinks the gap further than (:func:`explains_more`:
            the effect is then not the structure's stand-in); ``None`` otherwise.
        noise: the process noise the named effect was named in place of (:func:`past_noise`; ``effect`` is then its
            entry beyond the noise, or, with ``noise_after``, its entry in the box); ``None`` otherwise.
        noise_after: the noise's entry ranked beyond the named disturbance, where it added nothing significant;
            ``None`` otherwise.
    """

    under_fitted: Refit | None = None
    structure: Structure | None = None
    effect: Entry | None = None
    tied_with: tuple[str, ...] = ()
    outshrinks: Structure | None = None
    noise: Entry | None = None
    noise_after: Entry | None = None

    @property
    def settled(self) -> bool:
        """Whether effects were judged at all: not when the re-fitted base is still converging."""
        return self.under_fitted is None or self.under_fitted.settled

    def __str__(self) -> str:
        return sentence(self)


NOISE = "process_noise"
"""The candidate that models process noise: named only when no other effect shrinks the gap beyond it
(:func:`past_noise`)."""


SIMPLER: Mapping[str, str] = MappingProxyType({"actuator_lag": "input_delay"})
"""The one tie settled by a fixed preference rather than by shrink: a named effect and the one named in its place
when the two are tied, a servo lag on every stick axis and the input delay, which a lag of a similar size on every
axis stands in for. Other ties keep the larger shrink first."""


def simpler(effect: Entry, tied_with: Sequence[str], pool: Sequence[Entry]) -> Entry:
    """``effect``, or the first entry of ``pool`` (the ranking ``effect`` was named from, best first) of its
    :data:`SIMPLER` stand-in when that is among ``tied_with``."""
    other = SIMPLER.get(effect.effect)
    if other is None or other not in tied_with:
        return effect
    return next((e for e in pool if e.effect == other), effect)


def credited_past_noise(entry: Entry) -> bool:
    """Whether an effect ranked beyond process noise (:func:`~jaxheli.gap.noise_last.beyond_noise`) is named in its
    place: significant there, and its training flight's likelihood ratio over the noise alone at
    :data:`~jaxheli.gap.significance.LR_P` or less: beyond a disturbance model every held-out shrink is small and
    noisy (the design figures: ``docs/blind_history.md``, "process noise named last")."""
    return bool(entry.significant and entry.lr.p_value <= THRESHOLDS.lr_p)


def past_noise(
    ranking: Sequence[Entry], beyond: Sequence[Entry] = (), noise_beyond: Mapping[str, Entry] = MappingProxyType({}),
) -> Entry | None:
    """The effect named in place of process noise when that is the best significant entry of ``ranking``: the best
    entry of ``beyond`` (the effects the filter does not read, ranked again with the noise freed in every fit,
    :func:`~jaxheli.gap.noise_last.beyond_noise`) credited there (:func:`credited_past_noise`), else the best
    significant disturbance of ``ranking`` that the noise adds nothing significant beyond (``noise_beyond``: the
    noise's entry ranked beyond each, by name, :func:`~jaxheli.gap.noise_last.noise_beyond`); ``None`` otherwise.
    Process noise stands for whatever the base model leaves unexplained, a wrong structure's misfit included, so an
    effect that explains more is the finding."""
    best = next((e for e in ranking if e.significant), None)
    if best is None or best.effect != NOISE:
        return None
    return next((e for e in beyond if credited_past_noise(e)), None) or next(
        (e for e in ranking if e.significant and e.effect in noise_beyond and not noise_beyond[e.effect].significant),
        None)


def named(
    ranking: Sequence[Entry], beyond: Sequence[Entry] = (), noise_beyond: Mapping[str, Entry] = MappingProxyType({}),
) -> Entry | None:
    """The ranking entry of the effect a diagnosis names from the box's ``ranking`` (best first): the best
    significant one, or the effect named in its place beyond process noise (:func:`past_noise`); ``None``: none
    significant."""
    instead = past_noise(ranking, beyond, noise_beyond)
    if instead is None:
        return next((e for e in ranking if e.significant), None)
    return next(e for e in ranking if e.effect == instead.effect)


def explains_more(entry: Entry, structure: Structure | None) -> bool:
    """``entry``, ranked in the box, shrinks the validation gap at least as far as the significant ``structure``:
    a few effect parameters predict the validation flight as well as the base model re-fitted with every pinned
    parameter freed and its box widened, so the effect is not the structure's stand-in and is not judged again
    beyond it."""
    return bool(structure is not None and structure.significant and entry.shrink_pct >= structure.shrink_pct)


def structure_leads(ranking: Sequence[Entry], structure: Structure | None) -> bool:
    """The verdict names the base model's ``structure`` first: it is significant and no significant effect of
    ``ranking`` shrinks the gap as far (:func:`explains_more`)."""
    best = next((e for e in ranking if e.significant), None)
    return bool(structure is not None and structure.significant
                and not (best is not None and explains_more(best, structure)))


def find(
    ranking: Sequence[Entry], refit: Refit | None = None, structure: Structure | None = None,
    recheck: Sequence[Entry] = (), beyond_noise: Sequence[Entry] = (),
    noise_beyond: Mapping[str, Entry] = MappingProxyType({}),
) -> Verdict:
    """The verdict of a ``ranking`` (best first), the base re-fitted alone (``refit``, ``None``: frozen base), the
    base model's ``structure`` (:func:`~jaxheli.gap.structure.structure_hypothesis`), the entries ranked again
    beyond it (``recheck``, best first, :func:`~jaxheli.gap.ranking.staged`) and those of process noise's re-checks
    (``beyond_noise``, ``noise_beyond``, :func:`past_noise`). When the structure is named, the effect named is the
    significant one that shrinks the gap furthest beyond it."""
    if refit is not None and not refit.settled:
        return Verdict(under_fitted=refit)
    instead = past_noise(ranking, beyond_noise, noise_beyond)
    noise = None if instead is None else next(e for e in ranking if e.significant)
    best = named(ranking, beyond_noise, noise_beyond)
    leads = structure_leads(ranking, structure)
    effect = instead or best
    if instead is not None:
        effect = simpler(instead, instead.tied_with, beyond_noise)
    elif best is not None:
        if leads:
            significant = {e.effect for e in ranking if e.significant}
            effect = next((r for r in recheck if r.effect in significant), best)
        tied = next(e for e in ranking if e.effect == effect.effect).tied_with
        effect = simpler(effect, tied, (*recheck, *ranking) if leads else ranking)
        best = next(e for e in ranking if e.effect == effect.effect)
    return Verdict(
        under_fitted=refit if refit is not None and refit.under_fitted else None,
        structure=structure if leads else None,
        effect=effect,
        tied_with=effect.tied_with if instead is not None else best.tied_with if best is not None else (),
        outshrinks=structure if best is not None and explains_more(best, structure) else None,
        noise=noise,
        noise_after=noise_beyond.get(effect.effect) if instead is not None else None,
    )


def named_entry(verdict: Verdict, ranking: Sequence[Entry]) -> Entry | None:
    """The entry of the box's ``ranking`` for the effect ``verdict`` names (beyond the structure or beyond process
    noise, it may be another than :func:`named`'s), from which its size is re-identified on both flights; ``None``
    when it names none."""
    name = None if verdict.effect is None else verdict.effect.effect
    return next((e for e in ranking if e.effect == name), None)


def sentence(verdict: Verdict) -> str:
    """``verdict`` in words: the named effect, or ``"no significant effect"``; before it the structure when named,
    and first the under-fitted base (only that while it is still converging, with :func:`still_converging`)."""
    refit = verdict.under_fitted
    if refit is not None and not refit.settled:
        return f"{under_fitted(refit)} and {still_converging(refit)}: no effect is attributed until it settles"
    e = verdict.effect
    if e is None:
        text = "no significant effect"
    else:
        tie = f", tied with {' and '.join(verdict.tied_with)}" if verdict.tied_with else ""
        text = f"{e.effect} ({e.fitted.summary}){tie}: gap shrinks {e.shrink_pct:.1f} % on the validation flight"
        after = verdict.noise_after
        if after is not None:
            text += (f"; process noise adds {after.shrink_pct:.1f} +- {after.shrink_se_pct:.1f} % beyond it, not "
                     f"significant")
        elif verdict.noise is not None:
            text += f" beyond process noise ({verdict.noise.fitted.summary})"
        s = verdict.outshrinks
        if s is not None:
            text += f", more than the base model's structure ({s.summary}: {s.shrink_pct:.1f} +- {s.shrink_se_pct:.1f} %)"
    s = verdict.structure
    if s is not None:
        text = (f"base model structure: {s.summary}: re-fitting it in the physical ranges shrinks the validation gap "
                f"{s.shrink_pct:.1f} +- {s.shrink_se_pct:.1f} %; beyond that, {text}")
    return text if refit is None else f"{under_fitted(refit)}; beyond that, {text}"


def under_fitted(refit: Refit) -> str:
    """``"base model under-fitted: re-fitting it alone shrinks the validation gap 12.0 +- 2.5 %"``."""
    return (f"base model under-fitted: re-fitting it alone shrinks the validation gap {refit.shrink_pct:.1f} +- "
            f"{refit.shrink_se_pct:.1f} %")


def still_converging(refit: Refit) -> str:
    """``"it is still converging (training RSS down 3.2 % over the last 60 steps)"``."""
    return f"it is still converging (training RSS down {refit.progress_pct:.1f} % over the last {refit.steps} steps)"
