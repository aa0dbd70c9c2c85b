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

import numpy as np

from .._json import json_ready
from .._types import Float
from ..effects.registry import Fitted, json_number
from ..model import PARAM_NAMES


def _named(theta: Float[np.ndarray, "40"]) -> dict[str, float]:
    return dict(zip(PARAM_NAMES, map(float, np.asarray(theta))))


def _theta(named: Mapping[str, float | None]) -> Float[np.ndarray, "40"]:
    return np.array([json_number(named[n]) for n in PARAM_NAMES])


def _floats(named: Mapping[str, float | None]) -> dict[str, float]:
    return {k: json_number(v) for k, v in named.items()}


@dataclasses.dataclass(frozen=True)
class LRTest:
    """Likelihood-ratio test of a candidate against the reference on the training flight
    (:func:`~jaxheli.gap.significance.lr_test`)."""

    statistic: float
    dof: int
    p_value: float
    delta_aic: float

    def to_json(self) -> dict[str, Any]:
        """``{statistic, dof, p_value, delta_aic}``."""
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> LRTest:
        """The inverse of :meth:`to_json`."""
        return cls(json_number(data["statistic"]), int(data["dof"]), json_number(data["p_value"]), json_number(data["delta_aic"]))


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
    theta: Float[np.ndarray, "40"]
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
        return cls(data["effect"], Fitted.from_json(data), json_number(data["shrink_pct"]), json_number(data["shrink_se_pct"]),
                   _floats(data["shrink_by_channel"]), bool(data["significant"]), LRTest.from_json(data["lr"]),
                   json_number(data["p_value"]), json_number(data["gap_base"]), json_number(data["gap"]), bool(data["converged"]),
                   _theta(data["theta"]), _floats(data["nuisance"]), tuple(data["tied_with"]))


@dataclasses.dataclass(frozen=True)
class Refit:
    """The base model re-fitted alone, jointly re-identified (:func:`~jaxheli.gap.reference.base_refit`): its
    held-out shrink (%) of the given base's gap with standard error, both gaps (channel mean) and its gap per
    channel, whether the given base is ``under_fitted``, the solver's flag, ``progress_pct`` (how far its training
    RSS still fell over the candidates' budget), ``settled``, LM ``steps``, the re-fitted ``theta[40]`` and
    nuisance values."""

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
    theta: Float[np.ndarray, "40"]
    nuisance: Mapping[str, float]

    def to_json(self) -> dict[str, Any]:
        """``{"joint": True, ...}`` as ``jaxheli diagnose`` writes it (a frozen base, no re-fit, writes
        ``{"joint": False}``)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return {"joint": True, **fields, "gap_by_channel": dict(self.gap_by_channel), "theta": _named(self.theta),
                "nuisance": dict(self.nuisance)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Refit | None:
        """The inverse of :meth:`to_json` (``None`` for a frozen base)."""
        if not data["joint"]:
            return None
        return cls(json_number(data["shrink_pct"]), json_number(data["shrink_se_pct"]), json_number(data["gap_base"]), json_number(data["gap"]),
                   _floats(data["gap_by_channel"]), bool(data["under_fitted"]), bool(data["converged"]),
                   json_number(data["progress_pct"]), bool(data["settled"]), int(data["steps"]), _theta(data["theta"]),
                   _floats(data["nuisance"]))


@dataclasses.dataclass(frozen=True)
class Final:
    """The named effect re-identified with the base model on both flights (:func:`~jaxheli.gap.final_fit.final_fit`):
    its fit, the training plus validation RSS, LM ``steps``, the base parameters ``theta[40]`` and nuisance values
    fitted with it."""

    effect: str
    fitted: Fitted
    rss: float
    steps: int
    theta: Float[np.ndarray, "40"]
    nuisance: Mapping[str, float]

    def to_json(self) -> dict[str, Any]:
        """``{effect, params, where, summary, at_bound, evidence_z, rss, steps, theta, nuisance}``."""
        return {"effect": self.effect, **self.fitted.to_json(), "rss": self.rss, "steps": self.steps,
                "theta": _named(self.theta), "nuisance": dict(self.nuisance)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Final:
        """The inverse of :meth:`to_json`."""
        return cls(data["effect"], Fitted.from_json(data), json_number(data["rss"]), int(data["steps"]),
                   _theta(data["theta"]), _floats(data["nuisance"]))


@dataclasses.dataclass(frozen=True)
class Attribution:
    """Which effect (:func:`~jaxheli.gap.ranking.diagnose_effects`): the ranking, best first; the joint fit of
    the significant effects (``None`` unless two or more); the base re-fitted alone (``None``: frozen base); a
    sentence; the best significant effect re-identified on both flights (``None`` without one, or frozen); the
    restart filter's level every fit used."""

    ranking: tuple[Entry, ...]
    combination: Entry | None
    base_refit: Refit | None
    verdict: str
    final: Final | None
    track: float

    @property
    def shown(self) -> tuple[Entry, ...]:
        """The entries the before/after predictions show: the best, then the combination if any."""
        return (self.ranking[0],) + (() if self.combination is None else (self.combination,))

    def to_json(self) -> dict[str, Any]:
        """``{ranking, combination, base_refit, verdict, final, track}``."""
        return {"ranking": [e.to_json() for e in self.ranking],
                "combination": None if self.combination is None else self.combination.to_json(),
                "base_refit": {"joint": False} if self.base_refit is None else self.base_refit.to_json(), "verdict": self.verdict,
                "final": None if self.final is None else self.final.to_json(), "track": self.track}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Attribution:
        """The inverse of :meth:`to_json`."""
        return cls(tuple(Entry.from_json(e) for e in data["ranking"]),
                   None if data["combination"] is None else Entry.from_json(data["combination"]),
                   Refit.from_json(data["base_refit"]), data["verdict"],
                   None if data["final"] is None else Final.from_json(data["final"]), json_number(data["track"]))


@dataclasses.dataclass(frozen=True)
class Gap:
    """A model's gap on the validation flight: per channel and ``total`` (the channel mean)."""

    channel: Mapping[str, float]
    total: float

    def to_json(self) -> dict[str, Any]:
        """``{channel, total}``."""
        return {"channel": dict(self.channel), "total": self.total}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Gap:
        """The inverse of :meth:`to_json` (other keys ignored)."""
        return cls(_floats(data["channel"]), json_number(data["total"]))


@dataclasses.dataclass(frozen=True)
class FlightSummary:
    """A diagnosed flight: its source, sample count, step (s) and preprocessing records."""

    source: str
    samples: int
    dt: float
    preprocessing: tuple[Mapping[str, Any], ...]

    def to_json(self) -> dict[str, Any]:
        """``{source, samples, dt, preprocessing}``."""
        return {"source": self.source, "samples": self.samples, "dt": self.dt,
                "preprocessing": list(self.preprocessing)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> FlightSummary:
        """The inverse of :meth:`to_json`."""
        return cls(data["source"], int(data["samples"]), json_number(data["dt"]), tuple(data["preprocessing"]))


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """The whole diagnosis of a model on a training and a validation flight (:func:`~jaxheli.gap.diagnose.diagnose`).

    Attributes:
        model: what the model was given as (a file or set name, or ``"given parameters"``).
        flights: ``{"train", "validate"}`` summaries.
        outputs: the channels diagnosed; ``segment_s`` the predictions' restart interval (s).
        consistency: data-consistency findings of both flights, as JSON (:meth:`Finding.to_json` with a
            ``flight`` key).
        localisation: where the base model misses the validation flight (the training flight's under ``train``),
            as :func:`~jaxheli.gap.compare.localise_prediction` gives it.
        attribution: the ranked effects and what follows from them.
        gap_before: the base model's gap; ``gap_best`` and ``gap_combination`` those of the best entry and the
            combination (``None`` without one).
    """

    model: str
    flights: Mapping[str, FlightSummary]
    outputs: tuple[str, ...]
    segment_s: float
    consistency: tuple[Mapping[str, Any], ...]
    localisation: Mapping[str, Any]
    attribution: Attribution
    gap_before: Gap
    gap_best: Gap
    gap_combination: Gap | None

    def to_json(self) -> dict[str, Any]:
        """``diagnosis.json``: strict JSON values (:func:`~jaxheli._json.json_ready`), ``gap_after`` holding the
        shown entries' gaps under ``best`` and ``combination``, each with its ``effect``."""
        gaps = (self.gap_best, self.gap_combination)
        after = [{"effect": e.effect, **g.to_json()} for e, g in zip(self.attribution.shown, gaps)]
        return json_ready({
            "model": self.model,
            "flights": {role: f.to_json() for role, f in self.flights.items()},
            "outputs": list(self.outputs),
            "segment_s": self.segment_s,
            "consistency": list(self.consistency),
            "localisation": self.localisation,
            **self.attribution.to_json(),
            "gap_before": self.gap_before.to_json(),
            "gap_after": {"best": after[0], "combination": after[1] if len(after) > 1 else None},
        })

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Diagnosis:
        """The inverse of :meth:`to_json` (arrays of the localisation come back as lists)."""
        after = data["gap_after"]
        return cls(data["model"], {role: FlightSummary.from_json(f) for role, f in data["flights"].items()},
                   tuple(data["outputs"]), json_number(data["segment_s"]), tuple(data["consistency"]), data["localisation"],
                   Attribution.from_json(data), Gap.from_json(data["gap_before"]), Gap.from_json(after["best"]),
                   None if after["combination"] is None else Gap.from_json(after["combination"]))
