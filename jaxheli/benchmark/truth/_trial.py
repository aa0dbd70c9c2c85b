"""A truth trial: a drawn effect flown on a training and a held-out validation flight, and whether the effect is
detectable at all, decided here before any fit and apart from any method.

Detectable iff ``max_k rms_t(y_eff[t, k] - y_clean[t, k]) / sigma_k > 1``: the noise-free validation readings with
the effect (``y_eff``) and without it (``y_clean``; same excitation, the pilot's feedback re-flown in closed loop,
same seeds) differ in some channel ``k`` by more than that channel's sensor-noise std ``sigma_k``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._flight import NOISE, OUTPUTS, Effects, Record, fly
from ._kinds import KINDS, Dice, Injected, draw

VALIDATE_STYLE = "validate"
"""Excitation of every validation flight (:func:`~._pilot.excitation`)."""


@dataclasses.dataclass(frozen=True)
class TruthTrial:
    """``injected`` (:class:`~._kinds.Injected`) flown as ``train`` and ``validate`` (:class:`~._flight.Record`) with
    sensor-noise std ``noise`` per output; ``score`` the detectability ratio (module docstring), ``detectable``
    whether it exceeds 1."""

    injected: Injected
    train: Record
    validate: Record
    noise: np.ndarray
    score: float
    detectable: bool


def detectability(theta: np.ndarray, effects: Effects, validate: Record, noise: np.ndarray, *, seed: int,
                  duration: float, dt: float, outputs: tuple[str, ...] = OUTPUTS) -> float:
    """``max_k rms_t(y_eff - y_clean) / sigma_k`` of a validation flight ``validate`` flown with ``effects`` from
    ``seed``: the same flight re-flown without them gives ``y_clean`` (``noise`` holds ``sigma_k``)."""
    clean = fly(theta, Effects(), style=VALIDATE_STYLE, duration=duration, dt=dt, seed=seed, noise=noise,
                outputs=outputs)
    return detectability_ratio(validate.clean, clean.clean, noise)


def detectability_ratio(with_effect: np.ndarray, without: np.ndarray, noise: np.ndarray) -> float:
    """``max_k rms_t(with_effect - without) / noise_k``: noise-free readings ``[N, k]`` of one flight with and
    without an effect against each channel's sensor-noise std (the module docstring's criterion, > 1)."""
    rms = np.sqrt(np.mean((np.asarray(with_effect) - np.asarray(without)) ** 2, axis=0))
    return float(np.max(rms / np.asarray(noise)))


def truth_trial(kind: str, seed: int, theta: np.ndarray, *, style: str, noise: float = 1.0, strength: float = 1.0,
                duration: float = 30.0, dt: float = 0.05, outputs: tuple[str, ...] = OUTPUTS) -> TruthTrial:
    """Draw ``kind`` (:data:`~._kinds.KINDS`) at ``strength`` from ``seed`` and fly the 40 parameters ``theta`` with
    it: a training flight of excitation ``style`` (seed ``2 seed``) and a validation flight (seed ``2 seed + 1``),
    ``duration`` s logged every ``dt`` s, sensor noise ``noise`` times :data:`~._flight.NOISE`."""
    std = {c: noise * NOISE[c] for c in outputs}
    sigma = np.array([std[c] for c in outputs])
    rng = np.random.default_rng([seed, KINDS.index(kind)])
    injected = draw(kind, Dice(rng, strength, std, duration, dt, tuple(outputs)))
    common = dict(duration=duration, dt=dt, noise=sigma, outputs=tuple(outputs))
    train = fly(theta, injected.effects, style=style, seed=2 * seed, **common)
    validate = fly(theta, injected.effects, style=VALIDATE_STYLE, seed=2 * seed + 1, **common)
    score = detectability(theta, injected.effects, validate, sigma, seed=2 * seed + 1, duration=duration, dt=dt,
                          outputs=tuple(outputs))
    return TruthTrial(injected, train, validate, sigma, score, score > 1.0)
