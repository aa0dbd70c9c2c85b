"""The effect-augmented plant: the hover model plus every registered unmodelled effect, one step at a time.

All effects live in one flat parameter vector ``eta[E]`` (physical units, layout :func:`layout`); its
no-effect value :func:`no_effect` makes the plant the base model exactly. The same step functions fly the
truth of a blind synthetic flight (:func:`jaxheli.piloted_flight` with ``effect=``) and predict in the
diagnosis (:mod:`jaxheli.gap.predictor`), so an injected effect and its fitted model agree by construction.

The plant composes the terms of its registry's effects (:class:`~jaxheli.effects.record.Term`), per sample
``k`` (sample time ``dt``)::

    stick u_k -> command terms (transport delay, saturation) -> servo terms (servo lag) = applied u
              -> x_k+1 = Ad x_k + B u + E wind + dt (sum of the airframe terms: drag, rotor-speed yaw)
    output  y = reading terms (bias, drift) of mounting terms (misalignment, scale) of C x
"""

from __future__ import annotations

import functools
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..model import G_SI, N_INPUTS, STATE_NAMES, build_ab, output_indices
from ..sim.discretize import discretize
from .catalogue import EFFECTS
from .catalogue import GYROS as GYROS
from .record import AIRFRAME, SENSOR, STICK, Registry

GUST_STATES: tuple[str, ...] = ("u", "v", "w")
"""States whose speed derivatives the wind enters through (the aerodynamics see body velocity minus wind)."""


def layout(outputs: tuple[str, ...]) -> dict[str, slice]:
    """Slices of ``eta`` per parameter group of the library's effects for a flight with output channels
    ``outputs`` (each group is documented with its effect in :mod:`jaxheli.effects.catalogue`)."""
    return EFFECTS.layout(outputs)


def size(outputs: tuple[str, ...]) -> int:
    """Length ``E`` of ``eta`` for these outputs."""
    return EFFECTS.size(outputs)


def no_effect(outputs: tuple[str, ...]) -> Float[np.ndarray, "E"]:
    """``eta`` of the base model: every effect off (time constants of inactive states at harmless values)."""
    return EFFECTS.no_effect(outputs)


class Plant(eqx.Module):
    """Discrete hover model of one ``theta`` with the effects ``eta``; pure step functions for ``lax.scan``.

    Build with :func:`make_plant`. ``max_delay`` (samples, static) sizes the stick history of the delay.
    """

    Ad: Float[Array, "13 13"]
    B: Float[Array, "13 4"]
    E: Float[Array, "13 3"]
    C: Float[Array, "k 13"]
    eta: Float[Array, "E"]
    dt: float = eqx.field(static=True)
    outputs: tuple[str, ...] = eqx.field(static=True)
    max_delay: int = eqx.field(static=True)
    registry: Registry = eqx.field(static=True)

    def group(self, name: str) -> Array:
        """The slots of ``eta`` of parameter group ``name``."""
        return self.eta[self.registry.layout(self.outputs)[name]]

    def init_actuators(self) -> tuple[tuple[Any, ...], Float[Array, "4"], tuple[Any, ...]]:
        """States at trim: of the stick-path terms (e.g. the delay's stick history), of the servos (the
        applied sticks) and of the airframe terms (e.g. the rotor speed)."""
        return self._init(STICK), jnp.zeros(N_INPUTS), self._init(AIRFRAME)

    def actuate(
        self, history: tuple[Any, ...], servo: Float[Array, "4"], stick: Float[Array, "4"]
    ) -> tuple[tuple[Any, ...], Float[Array, "4"]]:
        """Sticks through the stick-path terms (delay, saturation, servo lag); returns their new states and
        the new servo (= applied) state."""
        states = []
        for term, state in zip(self.registry.terms(STICK), history):
            state, stick = term.apply(self, state, stick, servo)
            states.append(state)
        return tuple(states), stick

    def advance(
        self, x: Float[Array, "13"], rotor: tuple[Any, ...], applied: Float[Array, "4"], wind: Float[Array, "3"]
    ) -> tuple[Float[Array, "13"], tuple[Any, ...]]:
        """One sample of the plant: linear ZOH step plus the airframe terms (quadratic drag, rotor-speed yaw
        coupling), whose states ``rotor`` it advances too."""
        states, extra = [], jnp.zeros_like(x)
        for term, state in zip(self.registry.terms(AIRFRAME), rotor):
            state, rate = term.apply(self, state, x, applied)
            states.append(state)
            extra = extra + rate
        return self.Ad @ x + self.B @ applied + self.E @ wind + self.dt * extra, tuple(states)

    def measure(self, x: Float[Array, "13"], t: Float[Array, ""]) -> Float[Array, "k"]:
        """Sensor outputs of the state ``x`` at time ``t`` (s)."""
        return functools.reduce(lambda y, term: term.apply(self, y, t), self.registry.terms(SENSOR), self.C @ x)

    def unmeasure(self, y: Float[Array, "N k"], t: Float[Array, "N"]) -> Float[Array, "N k"]:
        """The output states behind a record of sensor readings ``y`` at times ``t`` (s): :meth:`measure` inverted."""
        return functools.reduce(lambda y, term: term.invert(self, y, t), self.registry.terms(SENSOR)[::-1], y)

    def _init(self, stages: tuple[str, ...]) -> tuple[Any, ...]:
        return tuple(None if term.init is None else term.init(self) for term in self.registry.terms(stages))


def make_plant(
    theta: Float[Array, "40"], eta: Float[Array, "E"], dt: float, outputs: tuple[str, ...], *,
    g: float = G_SI, max_delay: float = 0.3, registry: Registry = EFFECTS,
) -> Plant:
    """The augmented plant of ``theta`` and effects ``eta`` (laid out by ``registry``) at sample time ``dt``
    (s); delays up to ``max_delay`` s."""
    outputs = tuple(outputs)
    eta = jnp.asarray(eta)
    if eta.shape != (registry.size(outputs),):
        raise ValueError(f"make_plant: eta must have shape ({registry.size(outputs)},) for outputs {outputs}, "
                         f"got {eta.shape}")
    A, B = build_ab(theta, g)
    wind_in = -A[:, np.array([STATE_NAMES.index(s) for s in GUST_STATES])]
    d = discretize(A, jnp.concatenate([B, wind_in], axis=1), dt)
    C = jnp.asarray(np.eye(len(STATE_NAMES))[output_indices(outputs)])
    return Plant(d.Ad, d.B0[:, :N_INPUTS], d.B0[:, N_INPUTS:], C, eta, float(dt), outputs,
                 int(np.ceil(max_delay / dt)), registry)
