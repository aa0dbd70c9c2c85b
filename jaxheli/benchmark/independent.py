"""The independent truth simulator's trials (:mod:`jaxheli.benchmark.truth`) as the blind check's flights.

Turns a :class:`~jaxheli.benchmark.truth.TruthTrial` into a training and a validation :class:`FlightData` and
states, in the library's terms, what a right diagnosis names (:data:`~jaxheli.benchmark.truth.KIND_CANDIDATES`) and
the oracle: the nearest candidate started at the values its parameters share with the injected physics.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..data.flight import FlightData
from ..effects import registry as fx
from ..effects.plant import no_effect
from .structure_reach import StructureReach, structure_reach
from .truth import OUTPUTS, Record, TruthTrial, truth_trial


@dataclasses.dataclass(frozen=True)
class IndependentTrial:
    """Flights of an injected ``kind`` (its ``parts``), the ``candidates`` that count as right, the ``oracle``
    candidate (``"none"`` where no candidate shares a parameter) with its ``eta`` (library layout) at the shared
    values, the compared parameter ``primary`` and its true ``value``, the simulator's detectability
    (``score``, ``detectable``) and, where asked, how far a hover model alone takes the effect up (``reach``,
    :func:`~jaxheli.benchmark.structure_reach.structure_reach`)."""

    kind: str
    parts: tuple[str, ...]
    train: FlightData
    validate: FlightData
    candidates: tuple[str, ...]
    oracle: str
    eta: np.ndarray
    primary: str | None
    value: float
    score: float
    detectable: bool
    train_score: float
    resolvable: bool
    reach: StructureReach | None = None


def independent_trial(kind: str, seed: int, theta: np.ndarray, *, style: str, noise: float = 1.0,
                      strength: float = 1.0, duration: float = 30.0, dt: float = 0.05,
                      outputs: tuple[str, ...] = OUTPUTS, reach: bool = False) -> IndependentTrial:
    """:func:`~jaxheli.benchmark.truth.truth_trial` of ``kind`` and ``seed`` (passed through as given) on the truth
    ``theta``, training ``style``, noise multiple, strength, flight length and sample time, in the library's
    terms; with ``reach``, the effect's reach beyond the hover model too (a least-squares fit, seconds)."""
    trial = truth_trial(kind, seed, theta, style=style, noise=noise, strength=strength, duration=duration, dt=dt,
                        outputs=outputs)
    injected = trial.injected
    eta = no_effect(outputs)
    oracle = next((c for c in injected.candidates if c in injected.shared), "none")
    primary, value = None, 0.0
    if oracle != "none":
        slots = {p.name: p.slot for p in fx.params(oracle, outputs)}
        for name, v in injected.shared[oracle].items():
            eta[slots[name]] = v
        primary, value = next(iter(injected.shared[oracle].items()))
    flights = [_flight(trial, record, seed, role, outputs) for role, record in
               (("train", trial.train), ("validate", trial.validate))]
    found = structure_reach(theta, trial.train, trial.validate, trial.noise, outputs) if reach else None
    return IndependentTrial(kind, injected.parts, *flights, injected.candidates, oracle, eta, primary, float(value),
                            trial.score, trial.detectable, trial.train_score, trial.resolvable, found)


def _flight(trial: TruthTrial, record: Record, seed: int, role: str, outputs: tuple[str, ...]) -> FlightData:
    """One of ``trial``'s flights as :class:`FlightData` with the simulator's provenance."""
    injected = trial.injected
    metadata = {"generator": "jaxheli.benchmark.truth (independent truth simulator)", "role": role, "seed": seed,
                "dt": float(record.time[1] - record.time[0]), "noise": dict(zip(outputs, trial.noise.tolist())),
                "kind": injected.kind, "parts": list(injected.parts), "candidates": list(injected.candidates),
                "shared": injected.shared, "effects": dataclasses.asdict(injected.effects),
                "detectability": trial.score, "detectable": trial.detectable,
                "detectability_train": trial.train_score, "resolvable": trial.resolvable}
    return FlightData(record.time, record.sticks, record.measured, tuple(outputs),
                      source=f"independent truth flight ({injected.kind}, seed {seed}, {role})", metadata=metadata)
