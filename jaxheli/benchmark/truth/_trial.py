"""A truth trial: a drawn effect flown on a training and a held-out validation flight, and whether the effect is
detectable at all, decided here before any fit and apart from any method.

Detectable iff ``max_k rms_t(y_eff[t, k] - y_clean[t, k]) / sigma_k > 1``: the noise-free validation readings with
the effect (``y_eff``) and without it (``y_clean``; same excitation, the pilot's feedback re-flown in closed loop,
same seeds) differ in some channel ``k`` by more than that channel's sensor-noise std ``sigma_k``. Resolvable iff
detectable and the same holds on the training flight: a diagnosis that learns an effect from the training flight and
scores it on the validation flight can only name an effect that both flights show (a regulating pilot's sticks,
about 0.08, never reach a servo stop at 0.15 stick that the validation flight's 3-2-1-1 of 0.25 hits).
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
    sensor-noise std ``noise`` per output; ``score`` the validation flight's detectability ratio (module docstring),
    ``detectable`` whether it exceeds 1, ``train_score`` the training flight's."""

    injected: Injected
    train: Record
    validate: Record
    noise: np.ndarray
    score: float
    detectable: bool
    train_score: float

    @property
    def resolvable(self) -> bool:
        """Both flights show the effect above the sensor noise (module docstring)."""
        return self.detectable and self.train_score > 1.0


def detectability(theta: np.ndarray, flight: Record, noise: np.ndarray, *, seed: int, duration: float, dt: float,
                  outputs: tuple[str, ...] = OUTPUTS, style: str = VALIDATE_STYLE) -> float:
    """``max_k rms_t(y_eff - y_clean) / sigma_k`` of ``flight``, flown by ``theta`` with its effects from ``seed``
    with the excitation ``style``: the same flight re-flown without any effect gives ``y_clean`` (``noise`` holds
    ``sigma_k``)."""
    clean = fly(theta, Effects(), style=style, duration=duration, dt=dt, seed=seed, noise=noise, outputs=outputs)
    return detectability_ratio(flight.clean, clean.clean, noise)


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
    scores = [detectability(theta, record, sigma, seed=s, duration=duration, dt=dt, outputs=tuple(outputs),
                            style=flown) for record, s, flown in
              ((validate, 2 * seed + 1, VALIDATE_STYLE), (train, 2 * seed, style))]
    return TruthTrial(injected, train, validate, sigma, scores[0], scores[0] > 1.0, scores[1])
