"""The effect-augmented plant: the hover model plus every candidate unmodelled effect, one step at a time.

All effects live in one flat parameter vector ``eta[E]`` (physical units, layout :func:`layout`); its
no-effect value :func:`no_effect` makes the plant the base model exactly. The same step functions fly the
truth of a blind synthetic flight (:func:`jaxheli.piloted_flight` with ``effect=``) and predict in the
diagnosis (:mod:`jaxheli.gap.predictor`), so an injected effect and its fitted model agree by construction.

Signal path, per sample ``k`` (sample time ``dt``)::

    stick u_k -> transport delay (fractional, linear interpolation of the held sticks)
              -> saturation u / sqrt(1 + k_sat u^2)       (level 1 / sqrt(k_sat) stick)
              -> servo lag, backward Euler, time constant tau (s)
              -> x_k+1 = Ad x_k + B u + E wind + dt (Xuu u|u|, Yvv v|v|, rotor-speed yaw term)
    output  y = M (C x) + bias + drift t   (M: gyro scale factors and a yaw mounting misalignment)

Effects that are absent cost nothing in accuracy: every transform is the identity at its no-effect value.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..sim.discretize import discretize
from ..model import G_SI, N_INPUTS, STATE_NAMES, build_ab, output_indices

GUST_STATES: tuple[str, ...] = ("u", "v", "w")
"""States whose speed derivatives the wind enters through (the aerodynamics see body velocity minus wind)."""

_PAIRS = (("u", "v"), ("p", "q"), ("phi", "theta"))
"""Output pairs a yaw mounting misalignment rotates."""

GYROS: tuple[str, ...] = ("p", "q", "r")
"""Output channels a scale-factor error acts on (gyros)."""
_ROTOR_TAU = 0.5
_GUST_TAU = 1.0


def layout(outputs: tuple[str, ...]) -> dict[str, slice]:
    """Slices of ``eta`` per parameter group for a flight with output channels ``outputs``.

    ``delay[4]`` s, ``lag[4]`` s (lat lon ped col); ``sat[4]`` 1/stick^2; ``drag[2]`` ``Xuu, Yvv`` 1/m;
    ``rotor[2]`` yaw gain rad/s^2 per collective stick and time constant s; ``gust[3]`` std (m/s),
    correlation time (s) and the cut of the restart filter's white state noise (``track`` to
    ``track e^-|cut|``; the plant never uses it, :func:`jaxheli.gap.kalman.gust_filter` does); ``mis[4]``
    yaw misalignment rad and p, q, r scale-factor errors (fraction); ``bias[k]`` and ``drift[k]`` (channel
    units, per s).
    """
    sizes = (("delay", 4), ("lag", 4), ("sat", 4), ("drag", 2), ("rotor", 2), ("gust", 3), ("mis", 4),
             ("bias", len(outputs)), ("drift", len(outputs)))
    out, start = {}, 0
    for name, size in sizes:
        out[name] = slice(start, start + size)
        start += size
    return out


def size(outputs: tuple[str, ...]) -> int:
    """Length ``E`` of ``eta`` for these outputs."""
    return layout(outputs)["drift"].stop


def no_effect(outputs: tuple[str, ...]) -> Float[np.ndarray, "E"]:
    """``eta`` of the base model: every effect off (time constants of inactive states at harmless values)."""
    eta = np.zeros(size(outputs))
    lay = layout(outputs)
    eta[lay["rotor"].start + 1] = _ROTOR_TAU
    eta[lay["gust"].start + 1] = _GUST_TAU
    return eta


class Plant(eqx.Module):
    """Discrete hover model of one ``theta`` with the effects ``eta``; pure step functions for ``lax.scan``.

    Build with :func:`make_plant`. ``max_delay`` (samples, static) sizes the stick history of the delay.
    """

    Ad: Float[Array, "13 13"]
    B: Float[Array, "13 4"]
    E: Float[Array, "13 3"]
    C: Float[Array, "k 13"]
    M: Float[Array, "k k"]
    eta: Float[Array, "E"]
    dt: float = eqx.field(static=True)
    outputs: tuple[str, ...] = eqx.field(static=True)
    max_delay: int = eqx.field(static=True)

    def group(self, name: str) -> Array:
        return self.eta[layout(self.outputs)[name]]

    def init_actuators(self) -> tuple[Float[Array, "D 4"], Float[Array, "4"], Float[Array, ""]]:
        """Stick history, servo states and rotor-speed state at trim."""
        return jnp.zeros((self.max_delay + 2, N_INPUTS)), jnp.zeros(N_INPUTS), jnp.zeros(())

    def actuate(
        self, history: Float[Array, "D 4"], servo: Float[Array, "4"], stick: Float[Array, "4"]
    ) -> tuple[Float[Array, "D 4"], Float[Array, "4"]]:
        """Sticks through delay, saturation and servo lag; returns the new history and servo (= applied) state."""
        history = jnp.concatenate([stick[None, :], history[:-1]], axis=0)
        d = jnp.clip(jnp.abs(self.group("delay")) / self.dt, 0.0, float(self.max_delay))
        i0 = jnp.clip(jnp.floor(d), 0, self.max_delay).astype(jnp.int32)
        f = d - i0
        axes = jnp.arange(N_INPUTS)
        delayed = (1.0 - f) * history[i0, axes] + f * history[i0 + 1, axes]
        saturated = delayed / jnp.sqrt(1.0 + jnp.abs(self.group("sat")) * delayed**2)
        tau = jnp.abs(self.group("lag"))
        a = tau / (tau + self.dt)
        return history, a * servo + (1.0 - a) * saturated

    def advance(
        self, x: Float[Array, "13"], rotor: Float[Array, ""], applied: Float[Array, "4"], wind: Float[Array, "3"]
    ) -> tuple[Float[Array, "13"], Float[Array, ""]]:
        """One sample of the plant: linear ZOH step plus quadratic drag and the rotor-speed yaw coupling."""
        xuu, yvv = self.group("drag")
        gain, tau = self.group("rotor")
        tau = jnp.abs(tau) + 1e-6
        rotor_next = (tau * rotor + self.dt * gain * applied[3]) / (tau + self.dt)
        iu, iv, ir = (STATE_NAMES.index(s) for s in ("u", "v", "r"))
        extra = jnp.zeros_like(x).at[iu].set(xuu * x[iu] * jnp.abs(x[iu])).at[iv].set(yvv * x[iv] * jnp.abs(x[iv]))
        extra = extra.at[ir].set(rotor_next)
        return self.Ad @ x + self.B @ applied + self.E @ wind + self.dt * extra, rotor_next

    def measure(self, x: Float[Array, "13"], t: Float[Array, ""]) -> Float[Array, "k"]:
        """Sensor outputs of the state ``x`` at time ``t`` (s)."""
        return self.M @ (self.C @ x) + self.group("bias") + self.group("drift") * t

    def unmeasure(self, y: Float[Array, "N k"], t: Float[Array, "N"]) -> Float[Array, "N k"]:
        """The output states behind a record of sensor readings ``y`` at times ``t`` (s): :meth:`measure` inverted."""
        clean = y - self.group("bias")[None, :] - t[:, None] * self.group("drift")[None, :]
        return jnp.linalg.solve(self.M, clean.T).T


def make_plant(
    theta: Float[Array, "40"], eta: Float[Array, "E"], dt: float, outputs: tuple[str, ...], *,
    g: float = G_SI, max_delay: float = 0.3,
) -> Plant:
    """The augmented plant of ``theta`` and effects ``eta`` at sample time ``dt`` (s); delays up to ``max_delay`` s."""
    outputs = tuple(outputs)
    eta = jnp.asarray(eta)
    if eta.shape != (size(outputs),):
        raise ValueError(f"make_plant: eta must have shape ({size(outputs)},) for outputs {outputs}, got {eta.shape}")
    A, B = build_ab(theta, g)
    wind_in = -A[:, np.array([STATE_NAMES.index(s) for s in GUST_STATES])]
    d = discretize(A, jnp.concatenate([B, wind_in], axis=1), dt)
    C = jnp.asarray(np.eye(len(STATE_NAMES))[output_indices(outputs)])
    return Plant(d.Ad, d.B0[:, :N_INPUTS], d.B0[:, N_INPUTS:], C, _sensor_matrix(eta[layout(outputs)["mis"]], outputs),
                 eta, float(dt), outputs, int(np.ceil(max_delay / dt)))


def _sensor_matrix(mis: Float[Array, "4"], outputs: tuple[str, ...]) -> Float[Array, "k k"]:
    """``M``: scale factors on p, q, r, then a yaw rotation of the (u, v), (p, q), (phi, theta) pairs."""
    eps, *scale = mis
    k = len(outputs)
    diag = jnp.ones(k)
    for name, s in zip(GYROS, scale):
        if name in outputs:
            diag = diag.at[outputs.index(name)].add(s)
    R = jnp.eye(k)
    c, s = jnp.cos(eps), jnp.sin(eps)
    for a, b in _PAIRS:
        if a in outputs and b in outputs:
            i, j = outputs.index(a), outputs.index(b)
            R = R.at[i, i].set(c).at[i, j].set(s).at[j, i].set(-s).at[j, j].set(c)
    return R * diag[None, :]
