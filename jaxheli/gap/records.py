"""The diagnosis's results as frozen records: a ranking entry, the base model re-fitted alone, the named effect
re-identified on both flights, the attribution they make up and the whole diagnosis.

The records stay typed inside the library; ``to_json`` / ``from_json`` are for the edges only (the CLI, files,
the report, the blind benchmark's records). ``to_json`` gives plain Python values with the keys and key order
of the files ``jaxheli diagnose`` writes (:meth:`Diagnosis.to_json` makes them strict JSON with
:func:`~jaxheli._json.json_ready`: non-finite numbers become ``None``, and ``from_json`` reads ``None`` back as
NaN)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from .._json import json_ready
from ..effects.registry import Fitted
from ._record import Theta, _Flat, _json, _maybe, _named, _read, _write
from .localisation_record import Localisation


@dataclasses.dataclass(frozen=True)
class LRTest(_Flat):
    """Likelihood-ratio test of a candidate against the reference on the training flight
    (:func:`~jaxheli.gap.significance.lr_test`)."""

    statistic: float
    dof: int
    p_value: float
    delta_aic: float


@dataclasses.dataclass(frozen=True)
class Entry:
    """One ranked candidate effect (or a combination ``"a+b"``), fitted on the training flight and scored on the
    validation flight (:func:`~jaxheli.gap.significance.shrink_entries`).

    Attributes:
        effect: the candidate's name.
        fitted: its fitted values with standard errors and 95 % intervals, where it acts, in words
            (:func:`~jaxheli.effects.registry.report`).
        shrink_pct: held-out shrink (%) of the reference's gap; ``shrink_se_pct`` its paired standard error (%);
            ``shrink_by_channel`` per output channel (%).
        significant: past every test of :mod:`~jaxheli.gap.significance`; ``tied_with`` the significant
            candidates within its noise.
        lr: likelihood-ratio test on the training flight; ``p_value`` the one-sided window t-test.
        gap_base, gap: the reference's and the candidate's channel-mean gap on the validation flight.
        converged: the solver's flag.
        theta: ``[40]`` base parameters fitted with the effect; ``nuisance`` the nuisance values fitted with it,
            by name (empty unless re-identified jointly).
    """

    effect: str
    fitted: Fitted
    shrink_pct: float
    shrink_se_pct: float
    shrink_by_channel: Mapping[str, float]
    significant: bool
    lr: LRTest
    p_value: float
    gap_base: float
    gap: float
    converged: bool
    theta: Theta
    nuisance: Mapping[str, float]
    tied_with: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The entry as ``jaxheli diagnose`` writes it; parameters named as in :data:`~jaxheli.PARAM_NAMES`."""
        f = self.fitted.to_json()
        return {"effect": self.effect, "where": f["where"], "params": f["params"], "shrink_pct": self.shrink_pct,
                "shrink_se_pct": self.shrink_se_pct, "shrink_by_channel": dict(self.shrink_by_channel),
                "significant": self.significant, "at_bound": f["at_bound"], "evidence_z": f["evidence_z"],
                "lr": self.lr.to_json(), "p_value": self.p_value, "gap_base": self.gap_base, "gap": self.gap,
                "summary": f["summary"], "converged": self.converged, "theta": _named(self.theta),
                "nuisance": dict(self.nuisance), "tied_with": list(self.tied_with)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Entry:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, fitted=Fitted.from_json(data), lr=LRTest.from_json(data["lr"]))


@dataclasses.dataclass(frozen=True)
class Refit:
    """The base model re-fitted alone, jointly re-identified (:func:`~jaxheli.gap.reference.base_refit`): its
    held-out shrink (%) of the given base's gap with standard error, both gaps (channel mean) and its gap per
    channel, whether the given base is ``under_fitted``, the solver's flag, ``progress_pct`` (how far its training
    RSS still fell over the candidates' budget), ``settled``, LM ``steps``, the re-fitted ``theta[40]`` and
    nuisance values; ``challenged``: a candidate's base parameters gave the reference a better basin
    (:func:`~jaxheli.gap.reference.challenge`), and ``followed``: how many candidate rows fitted better from it
    (:func:`~jaxheli.gap.reference.follow`)."""

    shrink_pct: float
    shrink_se_pct: float
    gap_base: float
    gap: float
    gap_by_channel: Mapping[str, float]
    under_fitted: bool
    converged: bool
    progress_pct: float
    settled: bool
    steps: int
    theta: Theta
    nuisance: Mapping[str, float]
    challenged: bool = False
    followed: int = 0

    def to_json(self) -> dict[str, Any]:
        """``{"joint": True, ...}`` as ``jaxheli diagnose`` writes it (a frozen base, no re-fit, writes
        ``{"joint": False}``)."""
        return {"joint": True, **_write(self)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Refit | None:
        """The inverse of :meth:`to_json` (``None`` for a frozen base; records written before the challenge's
        fields read as unchallenged)."""
        if not data["joint"]:
            return None
        return _read(cls, data, challenged=bool(data.get("challenged", False)), followed=int(data.get("followed", 0)))


@dataclasses.dataclass(frozen=True)
class Structure(_Flat):
    """The base model's structure as a hypothesis (:func:`~jaxheli.gap.structure.structure_hypothesis`): the
    reference re-fitted alone in the physical ranges, its held-out shrink (%) of the yardstick's gap with standard
    error, whether it is ``significant``, both gaps (channel mean) and its gap per channel; the pinned parameters it
    ``freed`` and those ``beyond`` the box (values by name), with the bound each ``crossed``; the re-fitted
    ``theta[40]`` and nuisance values."""

    shrink_pct: float
    shrink_se_pct: float
    significant: bool
    gap_base: float
    gap: float
    gap_by_channel: Mapping[str, float]
    freed: Mapping[str, float]
    beyond: Mapping[str, float]
    crossed: Mapping[str, float]
    theta: Theta
    nuisance: Mapping[str, float]

    @property
    def summary(self) -> str:
        """What moved, in words: ``"Nw freed (2.71), Mu beyond its bound (-0.18 past -0.1)"``."""
        moved = [f"{n} freed ({v:.3g})" for n, v in self.freed.items()]
        moved += [f"{n} beyond its bound ({v:.3g} past {self.crossed[n]:.3g})" for n, v in self.beyond.items()]
        return ", ".join(moved) or "no parameter left the box"


@dataclasses.dataclass(frozen=True)
class Final:
    """The named effect re-identified with the base model on both flights (:func:`~jaxheli.gap.final_fit.final_fit`):
    its fit, the training plus validation RSS, LM ``steps``, the base parameters ``theta[40]`` and nuisance values
    fitted with it."""

    effect: str
    fitted: Fitted
    rss: float
    steps: int
    theta: Theta
    nuisance: Mapping[str, float]

    def to_json(self) -> dict[str, Any]:
        """``{effect, params, where, summary, at_bound, evidence_z, rss, steps, theta, nuisance}``."""
        return {"effect": self.effect, **self.fitted.to_json(), **_write(self, "effect", "fitted")}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Final:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, fitted=Fitted.from_json(data))


@dataclasses.dataclass(frozen=True)
class Attribution:
    """Which effect (:func:`~jaxheli.gap.ranking.diagnose_effects`): the ranking, best first; the joint fit of
    the significant effects (``None`` unless two or more); the base re-fitted alone (``None``: frozen base); a
    sentence; the best significant effect re-identified on both flights (``None`` without one, or frozen); the
    restart filter's level every fit used; the base model's structure as a hypothesis (``None``: frozen base, or
    a box that already holds the physical ranges); the effects significant in the box ranked again beyond the
    structure, in the physical ranges (``recheck``, :func:`~jaxheli.gap.ranking.staged`: an effect stays significant
    only where it is in both)."""

    ranking: tuple[Entry, ...]
    combination: Entry | None
    base_refit: Refit | None
    verdict: str
    final: Final | None
    track: float
    structure: Structure | None = None
    recheck: tuple[Entry, ...] = ()

    @property
    def shown(self) -> tuple[Entry, ...]:
        """The entries the before/after predictions show: the best, then the combination if any."""
        return (self.ranking[0],) + (() if self.combination is None else (self.combination,))

    def to_json(self) -> dict[str, Any]:
        """``{ranking, combination, base_refit, structure, recheck, verdict, final, track}``."""
        return {"ranking": [e.to_json() for e in self.ranking], "combination": _json(self.combination),
                "base_refit": _json(self.base_refit) or {"joint": False}, "structure": _json(self.structure),
                "recheck": [e.to_json() for e in self.recheck], "verdict": self.verdict, "final": _json(self.final),
                "track": self.track}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Attribution:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, ranking=tuple(map(Entry.from_json, data["ranking"])),
                     combination=_maybe(Entry.from_json, data["combination"]),
                     base_refit=Refit.from_json(data["base_refit"]), final=_maybe(Final.from_json, data["final"]),
                     structure=_maybe(Structure.from_json, data.get("structure")),
                     recheck=tuple(map(Entry.from_json, data.get("recheck", ()))))


@dataclasses.dataclass(frozen=True)
class Gap(_Flat):
    """A model's gap on the validation flight: per channel and ``total`` (the channel mean)."""

    channel: Mapping[str, float]
    total: float


@dataclasses.dataclass(frozen=True)
class FlightSummary(_Flat):
    """A diagnosed flight: its source, sample count, step (s) and preprocessing records."""

    source: str
    samples: int
    dt: float
    preprocessing: tuple[Mapping[str, Any], ...]


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """The whole diagnosis of a model on a training and a validation flight (:func:`~jaxheli.gap.diagnose.diagnose`).

    Attributes:
        model: what the model was given as (a file or set name, or ``"given parameters"``).
        flights: ``{"train", "validate"}`` summaries.
        outputs: the channels diagnosed; ``segment_s`` the predictions' restart interval (s), ``restart`` where
            they restart (:data:`~jaxheli.gap.predictor.RESTARTS`; ``"filter"`` in files written before it was
            recorded).
        consistency: data-consistency findings of both flights, as JSON (:meth:`Finding.to_json` with a
            ``flight`` key).
        localisation: where the base model misses the validation flight
            (:func:`~jaxheli.gap.compare.localise_prediction`).
        attribution: the ranked effects and what follows from them.
        gap_before: the base model's gap; ``gap_best`` and ``gap_combination`` those of the best entry and the
            combination (``None`` without one).
        localisation_train: where it misses the training flight (``None``: not localised; JSON: the
            localisation's ``train``).
    """

    model: str
    flights: Mapping[str, FlightSummary]
    outputs: tuple[str, ...]
    segment_s: float
    consistency: tuple[Mapping[str, Any], ...]
    localisation: Localisation
    attribution: Attribution
    gap_before: Gap
    gap_best: Gap
    gap_combination: Gap | None
    localisation_train: Localisation | None = None
    restart: str = "filter"

    def to_json(self) -> dict[str, Any]:
        """``diagnosis.json``: strict JSON values (:func:`~jaxheli._json.json_ready`), ``gap_after`` holding the
        shown entries' gaps under ``best`` and ``combination``, each with its ``effect``."""
        gaps = (self.gap_best, self.gap_combination)
        after = [{"effect": e.effect, **g.to_json()} for e, g in zip(self.attribution.shown, gaps)]
        train = {} if self.localisation_train is None else {"train": self.localisation_train.to_json()}
        return json_ready({
            "model": self.model,
            "flights": {role: f.to_json() for role, f in self.flights.items()},
            "outputs": list(self.outputs),
            "segment_s": self.segment_s,
            "restart": self.restart,
            "consistency": list(self.consistency),
            "localisation": {**self.localisation.to_json(), **train},
            **self.attribution.to_json(),
            "gap_before": self.gap_before.to_json(),
            "gap_after": {"best": after[0], "combination": after[1] if len(after) > 1 else None},
        })

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Diagnosis:
        """The inverse of :meth:`to_json`."""
        after, local = data["gap_after"], data["localisation"]
        return _read(cls, data, flights={role: FlightSummary.from_json(f) for role, f in data["flights"].items()},
                     localisation=Localisation.from_json(local),
                     localisation_train=_maybe(Localisation.from_json, local.get("train")),
                     attribution=Attribution.from_json(data), restart=data.get("restart", "filter"),
                     gap_before=Gap.from_json(data["gap_before"]), gap_best=Gap.from_json(after["best"]),
                     gap_combination=_maybe(Gap.from_json, after["combination"]))
