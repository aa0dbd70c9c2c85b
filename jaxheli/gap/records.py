"""The diagnosis's results as frozen records: the attribution (the ranked effects and what follows from them) and the
whole diagnosis; the records of single candidates (:mod:`~jaxheli.gap.candidate_records`) are re-exported here.

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
from ._record import _Flat, _json, _maybe, _read
from .candidate_records import Entry as Entry, Final as Final, LRTest as LRTest, Refit as Refit
from .candidate_records import Structure as Structure
from ..data.flight import FlightData
from .headline import headline
from .localisation_record import Localisation
from .verdict import Verdict, find


@dataclasses.dataclass(frozen=True)
class Attribution:
    """Which effect (:func:`~jaxheli.gap.ranking.diagnose_effects`): the ranking, best first; the joint fit of the
    significant effects (``None`` unless two or more); the base re-fitted alone (``None``: frozen base); the named
    effect (:func:`~jaxheli.gap.verdict.named`) re-identified on both flights (``None`` without one, or frozen); the
    restart filter's level every fit used; the base model's structure as a hypothesis (``None``: frozen base, or a
    box that already holds the physical ranges); the effects ranked again beyond the structure, in the physical
    ranges (``recheck``, :func:`~jaxheli.gap.ranking.staged`: where an effect is significant beyond the structure,
    :data:`~jaxheli.gap.ranking.RECHECK`); the effects ranked again beyond process noise when that leads
    (``beyond_noise``, :func:`~jaxheli.gap.noise_last.beyond_noise`) and the noise ranked beyond other filtered
    disturbances, by name (``noise_beyond``, :func:`~jaxheli.gap.noise_last.noise_beyond`). What they add up to:
    :attr:`verdict`."""

    ranking: tuple[Entry, ...]
    combination: Entry | None
    base_refit: Refit | None
    final: Final | None
    track: float
    structure: Structure | None = None
    recheck: tuple[Entry, ...] = ()
    beyond_noise: tuple[Entry, ...] = ()
    noise_beyond: Mapping[str, Entry] = dataclasses.field(default_factory=dict)

    @property
    def shown(self) -> tuple[Entry, ...]:
        """The entries the before/after predictions show: the best, then the combination if any."""
        return (self.ranking[0],) + (() if self.combination is None else (self.combination,))

    @property
    def verdict(self) -> Verdict:
        """What the ranking, the base re-fitted alone, the structure and the re-check found
        (:func:`~jaxheli.gap.verdict.find`; ``str()`` of it: the sentence ``diagnosis.json`` holds)."""
        return find(self.ranking, self.base_refit, self.structure, self.recheck, self.beyond_noise,
                    self.noise_beyond)

    def to_json(self) -> dict[str, Any]:
        """``{ranking, combination, base_refit, structure, recheck, beyond_noise, noise_beyond, verdict, final,
        track}``."""
        return {"ranking": [e.to_json() for e in self.ranking], "combination": _json(self.combination),
                "base_refit": _json(self.base_refit) or {"joint": False}, "structure": _json(self.structure),
                "recheck": [e.to_json() for e in self.recheck],
                "beyond_noise": [e.to_json() for e in self.beyond_noise],
                "noise_beyond": {k: e.to_json() for k, e in self.noise_beyond.items()}, "verdict": str(self.verdict),
                "final": _json(self.final), "track": self.track}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Attribution:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, ranking=tuple(map(Entry.from_json, data["ranking"])),
                     combination=_maybe(Entry.from_json, data["combination"]),
                     base_refit=Refit.from_json(data["base_refit"]), final=_maybe(Final.from_json, data["final"]),
                     structure=_maybe(Structure.from_json, data.get("structure")),
                     recheck=tuple(map(Entry.from_json, data.get("recheck", ()))),
                     beyond_noise=tuple(map(Entry.from_json, data.get("beyond_noise", ()))),
                     noise_beyond={k: Entry.from_json(v) for k, v in data.get("noise_beyond", {}).items()})


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
        validated: the validation flight as diagnosed (its channels, at the diagnosis's step, corrected when asked):
            what the plots show; not written to JSON (``None`` when read back).
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
    validated: FlightData | None = dataclasses.field(default=None, compare=False, repr=False)

    @property
    def headline(self) -> str:
        """The first line in words (:func:`~jaxheli.gap.headline.headline`): the significant consistency findings,
        then what was found, or where an unexplained gap lies."""
        return headline(self.attribution.verdict, self.consistency, self.localisation.summary)

    def to_json(self) -> dict[str, Any]:
        """``diagnosis.json``: strict JSON values (:func:`~jaxheli._json.json_ready`), ``gap_after`` holding the
        shown entries' gaps under ``best`` and ``combination``, each with its ``effect``, and the :attr:`headline`."""
        gaps = (self.gap_best, self.gap_combination)
        after = [{"effect": e.effect, **g.to_json()} for e, g in zip(self.attribution.shown, gaps)]
        train = {} if self.localisation_train is None else {"train": self.localisation_train.to_json()}
        return json_ready({
            "model": self.model,
            "headline": self.headline,
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
                     attribution=Attribution.from_json(data), restart=data.get("restart", "filter"), validated=None,
                     gap_before=Gap.from_json(data["gap_before"]), gap_best=Gap.from_json(after["best"]),
                     gap_combination=_maybe(Gap.from_json, after["combination"]))
