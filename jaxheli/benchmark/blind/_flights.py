"""A blind trial's training and validation flights by either truth simulator, and the noise-free pairs (with the
effect, re-flown without it) whose difference decides, before any fit, whether the effect is detectable."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...data.flight import FlightData
from ...synth.piloted import DEFAULT_NOISE, DEFAULT_OUTPUTS, piloted_flight
from .. import truth as independent_truth
from ..independent import independent_trial
from ._injection import KINDS, Injection, sample_injection
from ._scenario import STYLES, VALIDATE_EXCITATION, Scenario, scenario

TRUTHS_SIM: dict[str, tuple[str, ...]] = {"library": KINDS, "independent": independent_truth.KINDS}
"""Truth simulators of the blind check and the kinds each injects: the library's own piloted flights
(:func:`blind_flights`) or the independent simulator (:mod:`jaxheli.benchmark.truth`, :func:`trial_flights`)."""


def blind_flights(injection: Injection, seed: int, where: Scenario, *, duration: float = 30.0, dt: float = 0.05,
                  outputs: tuple[str, ...] = DEFAULT_OUTPUTS) -> tuple[FlightData, FlightData]:
    """Training (``where``'s style) and validation flights of ``where``'s truth plus ``injection`` at its noise
    level, seeds ``2 seed`` and ``2 seed + 1``."""
    common = dict(duration=duration, dt=dt, outputs=outputs, effect=injection.eta, gust=injection.gust,
                  gust_tau=injection.gust_tau, noise=where.noise)
    train = piloted_flight(where.theta, excitation=STYLES[where.style], seed=2 * seed, **common)
    validate = piloted_flight(where.theta, excitation=VALIDATE_EXCITATION, seed=2 * seed + 1, **common)
    return train, validate


def _library_seeds(kind: str, seed: int) -> tuple[int, int]:
    """The library simulator's seeds of trial ``seed`` of ``kind``: its injection's and its flights'."""
    return 7919 * seed + 101 * KINDS.index(kind), 7919 * seed + KINDS.index(kind)


def _library_pair(injection: Injection, seed: int, where: Scenario, *, duration: float, dt: float,
                  outputs: tuple[str, ...], train: bool = False) -> tuple[FlightData, FlightData, np.ndarray]:
    """The library simulator's validation flight (``train``: its training flight; :func:`blind_flights`) flown
    noise-free with ``injection`` and again without it (same excitation and seed, the pilot's feedback re-flown), and
    the trial's sensor-noise std per output."""
    excitation, flight_seed = (STYLES[where.style], 2 * seed) if train else (VALIDATE_EXCITATION, 2 * seed + 1)
    common = dict(duration=duration, dt=dt, outputs=outputs, excitation=excitation, seed=flight_seed, noise=0.0)
    flown = piloted_flight(where.theta, effect=injection.eta, gust=injection.gust, gust_tau=injection.gust_tau,
                           **common)
    bare = piloted_flight(where.theta, **common)
    return flown, bare, np.array([where.noise * DEFAULT_NOISE[c] for c in outputs])


def _library_detectability(injection: Injection, seed: int, where: Scenario, *, duration: float, dt: float,
                           outputs: tuple[str, ...], train: bool = False) -> float:
    """The library simulator's detectability of ``injection``, decided before any fit: :func:`_library_pair` scored
    by :func:`~jaxheli.benchmark.truth.detectability_ratio` against the trial's sensor-noise std."""
    flown, bare, sigma = _library_pair(injection, seed, where, duration=duration, dt=dt, outputs=outputs, train=train)
    return independent_truth.detectability_ratio(flown.outputs, bare.outputs, sigma)


def noise_free_pair(truth: str, kind: str, seed: int, *, train: bool = False, duration: float = 30.0,
                    dt: float = 0.05, outputs: tuple[str, ...] = DEFAULT_OUTPUTS) -> tuple[tuple, tuple, np.ndarray]:
    """Trial ``seed`` of ``kind``'s validation flight (``train``: its training flight) by the ``truth`` simulator
    (:data:`TRUTHS_SIM`) as the blind check flies it, noise-free, with its effect and re-flown without it (each
    ``(time, sticks, readings)``), and the sensor-noise std per output: the pair its detectability compares."""
    where = scenario(seed)
    if truth == "independent":
        trial = independent_truth.truth_trial(kind, seed, where.theta, style=where.style, noise=where.noise,
                                              strength=where.strength, duration=duration, dt=dt, outputs=outputs)
        flown, style, flight_seed = ((trial.train, where.style, 2 * seed) if train
                                     else (trial.validate, independent_truth.VALIDATE_STYLE, 2 * seed + 1))
        clean = independent_truth.fly(where.theta, independent_truth.Effects(), style=style, duration=duration,
                                      dt=dt, seed=flight_seed, noise=trial.noise, outputs=outputs)
        return ((flown.time, flown.sticks, flown.clean), (clean.time, clean.sticks, clean.clean), trial.noise)
    injection_seed, flight_seed = _library_seeds(kind, seed)
    inj = sample_injection(kind, injection_seed, outputs, duration, where.strength)
    flown, bare, sigma = _library_pair(inj, flight_seed, where, duration=duration, dt=dt, outputs=outputs,
                                       train=train)
    return (flown.time, flown.inputs, flown.outputs), (bare.time, bare.inputs, bare.outputs), sigma


def trial_flights(
    truth: str, kind: str, seed: int, where: Scenario, *, duration: float, dt: float, outputs: tuple[str, ...],
) -> tuple[Injection, FlightData, FlightData, tuple[str, ...], dict[str, Any]]:
    """A trial's flights by the ``truth`` simulator (:data:`TRUTHS_SIM`): ``(injection, train, validate, right,
    facts)``, ``injection`` the library kind the oracle fits at its true values, ``right`` the kinds a correct
    diagnosis names, ``facts`` what the record adds (the independent simulator's detectability, the residual a hover
    model fitted alone leaves of the effect, :func:`~jaxheli.benchmark.structure_reach.structure_reach`, and parts)."""
    if truth == "library":
        injection_seed, flight_seed = _library_seeds(kind, seed)
        inj = sample_injection(kind, injection_seed, outputs, duration, where.strength)
        train, validate = blind_flights(inj, flight_seed, where, duration=duration, dt=dt)
        score, train_score = (_library_detectability(inj, flight_seed, where, duration=duration,
                                                     dt=dt, outputs=outputs, train=role) for role in (False, True))
        return inj, train, validate, (kind,), {"detectability": score, "detectable": score > 1.0,
                                               "detectability_train": train_score,
                                               "resolvable": score > 1.0 and train_score > 1.0}
    if truth == "independent":
        ind = independent_trial(kind, seed, where.theta, style=where.style, noise=where.noise,
                                strength=where.strength, duration=duration, dt=dt, outputs=outputs, reach=True)
        inj = Injection(ind.oracle, ind.eta, 0.0, 1.0, ind.primary, ind.value)
        return inj, ind.train, ind.validate, ind.candidates, {
            "oracle_kind": ind.oracle, "parts": list(ind.parts), "right": list(ind.candidates),
            "detectability": ind.score, "detectable": ind.detectable, "detectability_train": ind.train_score,
            "resolvable": ind.resolvable, "structure_reach": ind.reach.beyond,
            "structure_reach_train": ind.reach.train}
    raise ValueError(f"blind trial: unknown truth simulator {truth!r}; simulators are {tuple(TRUTHS_SIM)}")
