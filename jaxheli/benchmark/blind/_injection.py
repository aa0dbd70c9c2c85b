"""The effect a library-simulator trial withholds: one kind of the registry at a random realistic magnitude (or
none), and the same injection on fewer channels."""

from __future__ import annotations

import dataclasses

import numpy as np

from ...effects import registry as fx
from ...effects.catalogue import EFFECTS
from ...effects.plant import no_effect
from ...synth.piloted import DEFAULT_NOISE, DEFAULT_OUTPUTS

KINDS: tuple[str, ...] = fx.ALL + ("none",)
"""Effect kinds of the blind check: every candidate plus the effect-free control."""


@dataclasses.dataclass(frozen=True)
class Injection:
    """A withheld effect: ``eta`` of the truth, gust std (m/s) and time constant (s), the primary parameter."""

    kind: str
    eta: np.ndarray
    gust: float
    gust_tau: float
    primary: str | None
    value: float


def sample_injection(kind: str, seed: int, outputs: tuple[str, ...] = DEFAULT_OUTPUTS, duration: float = 30.0,
                     strength: float = 1.0) -> Injection:
    """Draw ``kind`` at a random realistic magnitude by its registry entry's sampler (``numpy`` generator
    seeded by ``seed``; ranges in :mod:`jaxheli.effects.catalogue`) for a flight of ``duration`` s with the
    synthetic flights' measurement noise (:data:`~jaxheli.synth.piloted.DEFAULT_NOISE`), its size parameters
    (and wind) times ``strength``, each kept within 80 % of its physical bound (so none equals a fit's start: a
    saturation's further start is 90, :mod:`jaxheli.effects.catalogue`)."""
    if kind not in KINDS:
        raise ValueError(f"sample_injection: unknown kind {kind!r}; kinds are {KINDS}")
    if kind == "none":
        return Injection(kind, no_effect(outputs), 0.0, 1.0, None, 0.0)
    eta, draw = EFFECTS.inject(kind, seed, outputs, DEFAULT_NOISE, duration)
    for p in fx.params(kind, outputs):
        if p.name in draw.values and not p.shape:
            eta[p.slot] = np.clip(strength * eta[p.slot], -0.8 * p.bound, 0.8 * p.bound)
    primary = next(p for p in fx.params(kind, outputs) if p.name == draw.primary)
    return Injection(kind, eta, float(strength * draw.gust), float(draw.gust_tau), draw.primary,
                     float(eta[primary.slot]))


def _restrict(inj: Injection, outputs: tuple[str, ...]) -> Injection:
    """``inj`` on the channels ``outputs`` alone, as a user diagnoses a flight whose constant channels (a sensor
    quantised coarser than its channel moves) are left out: each effect parameter that still exists keeps its
    value."""
    eta = np.asarray(no_effect(outputs), np.float64).copy()
    kept = fx.params(inj.kind, outputs) if inj.kind != "none" else ()
    full = {p.name: p.slot for p in fx.params(inj.kind, DEFAULT_OUTPUTS)} if kept else {}
    for p in kept:
        eta[p.slot] = inj.eta[full[p.name]]
    if inj.primary in {p.name for p in kept}:
        return dataclasses.replace(inj, eta=eta)
    return dataclasses.replace(inj, eta=eta, primary=None, value=0.0)
