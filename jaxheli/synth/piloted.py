"""Piloted synthetic flights: the truth model flown in closed loop, as a real helicopter in hover is.

The hover model is open-loop unstable (``DESIGN.md`` section 1), so a synthetic flight is flown by a
simulated pilot whose sticks are feedback plus an excitation manoeuvre, saturated to ``[-1, 1]``; the
record holds the sticks actually applied and the noisy measured states, as a flight log does.
"""

from __future__ import annotations

import dataclasses
import functools
import types
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg

from .._types import Array, ArrayLike, Float
from ..sim.discretize import discretize
from .excitation import Excitation
from ..data.flight import FlightData
from ..effects.plant import Plant, layout, make_plant, size
from ..model import G_SI, INPUT_NAMES, MEASURABLE, N_PARAMS, STATE_NAMES, TABLE2, build_ab, output_indices

DEFAULT_OUTPUTS: tuple[str, ...] = ("u", "v", "p", "q", "phi", "theta", "w", "r")
"""Output channels of a synthetic flight: what an IMU, attitude estimator and GPS give."""

DEFAULT_NOISE: Mapping[str, float] = types.MappingProxyType({
    "u": 0.05, "v": 0.05, "w": 0.05,
    "p": 0.015, "q": 0.015, "r": 0.015,
    "phi": 0.005, "theta": 0.005, "a": 0.005, "b": 0.005,
})
"""Measurement noise standard deviation per channel (m/s, rad/s, rad): typical small-UAV sensor levels."""

_GUST_STATES = ("u", "v", "w")
_MAX_STATE: dict[str, float] = {
    "u": 1.0, "v": 1.0, "w": 1.0, "p": 1.0, "q": 1.0, "r": 1.0, "phi": 0.1, "theta": 0.1,
    "a": 0.05, "b": 0.05, "r_fb": 1.0, "c": 0.1, "d": 0.1,
}
"""Default Bryson limits of :class:`Pilot` (m/s, rad/s, rad)."""


@dataclasses.dataclass(frozen=True)
class Pilot:
    """An idealised pilot who knows the helicopter: a discrete LQR on the true (noise-free) state.

    Weights by Bryson's rule, ``Q = diag(1 / max_state^2)`` and ``R = I / max_stick^2``: the largest
    deviations per state (units of the parameter set: m/s, rad/s, rad) and the largest feedback stick the
    pilot accepts. ``max_state`` entries override the defaults by name. ``delay`` (s, rounded to samples)
    lags the pilot's feedback before it reaches the sticks; the LQR is designed on the delay-augmented
    model (the pilot anticipates its own lag), so the nominal loop is stable for any delay.
    """

    max_state: Mapping[str, float] = dataclasses.field(default_factory=dict)
    max_stick: float = 0.2
    delay: float = 0.0

    def __post_init__(self) -> None:
        unknown = sorted(set(self.max_state) - set(STATE_NAMES))
        if unknown:
            raise ValueError(f"Pilot: unknown state names {unknown} in max_state; states are {STATE_NAMES}")
        merged = types.MappingProxyType({**_MAX_STATE, **{k: float(v) for k, v in self.max_state.items()}})
        if not all(np.isfinite(v) and v > 0 for v in merged.values()):
            raise ValueError(f"Pilot: max_state values must be finite and > 0, got {self.max_state}")
        if not (np.isfinite(self.max_stick) and self.max_stick > 0):
            raise ValueError(f"Pilot: max_stick must be > 0, got {self.max_stick}")
        if not (np.isfinite(self.delay) and self.delay >= 0):
            raise ValueError(f"Pilot: delay must be >= 0 s, got {self.delay}")
        object.__setattr__(self, "max_state", merged)

    def gain(
        self, Ad: Float[ArrayLike, "13 13"], Bd: Float[ArrayLike, "13 4"], dt: float
    ) -> tuple[Float[np.ndarray, "4 z"], np.ndarray]:
        """LQR gain ``K`` on ``z = [x, pending sticks (oldest first)]`` and the closed-loop eigenvalues.

        The pilot commands ``-K z``; with no delay ``z = x``. Raises ``ValueError`` if the model cannot
        be stabilised.
        """
        Ad, Bd = np.asarray(Ad, dtype=np.float64), np.asarray(Bd, dtype=np.float64)
        n, m = Bd.shape
        lag = self.lag_samples(dt)
        Az = np.zeros((n + m * lag, n + m * lag))
        Bz = np.zeros((n + m * lag, m))
        Az[:n, :n] = Ad
        if lag:
            Az[:n, n : n + m] = Bd
            Az[n : n + m * (lag - 1), n + m :] = np.eye(m * (lag - 1))
            Bz[n + m * (lag - 1) :] = np.eye(m)
        else:
            Bz[:] = Bd
        Q = np.zeros_like(Az)
        Q[:n, :n] = np.diag([1.0 / self.max_state[s] ** 2 for s in STATE_NAMES])
        R = np.eye(m) / self.max_stick**2
        try:
            P = scipy.linalg.solve_discrete_are(Az, Bz, Q, R)
        except (np.linalg.LinAlgError, ValueError) as err:
            raise ValueError(f"Pilot: no stabilising LQR for this model ({err}); is it stabilisable?") from err
        K = np.linalg.solve(R + Bz.T @ P @ Bz, Bz.T @ P @ Az)
        poles = np.linalg.eigvals(Az - Bz @ K)
        if not np.all(np.abs(poles) < 1):
            raise ValueError(f"Pilot: the LQR loop is not stable (max |z| = {np.max(np.abs(poles)):.6g})")
        return K, poles

    def lag_samples(self, dt: float) -> int:
        """The reaction delay in whole samples of ``dt`` (s)."""
        return int(round(self.delay / dt))


def piloted_flight(
    theta: Float[ArrayLike, "40"] = TABLE2,
    *,
    duration: float = 60.0,
    dt: float = 0.01,
    excitation: Excitation | Float[ArrayLike, "N 4"] = Excitation(),
    seed: int = 0,
    noise: float | Mapping[str, float] = 1.0,
    gust: float = 0.0,
    gust_tau: float = 1.0,
    g: float = G_SI,
    pilot: Pilot = Pilot(),
    outputs: tuple[str, ...] = DEFAULT_OUTPUTS,
    effect: Float[ArrayLike, "E"] | None = None,
) -> FlightData:
    """Fly the truth model ``theta`` for ``duration`` s at sample time ``dt`` (s) under a pilot; record it.

    The truth (``build_ab(theta, g)``, ZOH at ``dt``: exact for sticks held over each sample) starts in
    trim (``x = 0``). Each sample the pilot's feedback plus ``excitation`` (an :class:`Excitation` or a
    ``[N, 4]`` stick array, ``N = round(duration / dt) + 1``) is saturated to ``[-1, 1]`` and applied.
    ``gust`` is the standard deviation of wind on u, v, w (velocity units of the parameter set),
    first-order low-pass white noise with correlation time ``gust_tau`` s, entering through the speed
    derivatives (the aerodynamics see body velocity minus wind): process noise. ``noise`` is a multiple
    of :data:`DEFAULT_NOISE` or a ``{channel: std}`` map naming every output. ``seed`` fixes gust and
    measurement noise (``jax.random``). Inputs are the applied sticks; outputs the measured ``outputs``.
    ``effect`` (``eta`` of :mod:`jaxheli.effects.plant` for ``outputs``) injects unmodelled effects into the
    truth plant (delay, lag, saturation between the recorded sticks and the rotor, drag, rotor-speed
    coupling, sensor errors); the pilot still designs on ``theta`` alone. Gusts stay ``gust``'s.
    """
    theta = np.asarray(theta, dtype=np.float64)
    _check(theta.shape == (N_PARAMS,) and bool(np.all(np.isfinite(theta))),
           f"piloted_flight: theta must be 40 finite parameters, got shape {theta.shape}")
    _check(dt > 0 and duration >= dt, f"piloted_flight: need 0 < dt <= duration, got {dt}, {duration}")
    _check(g > 0 and gust >= 0 and gust_tau > 0,
           f"piloted_flight: need g > 0, gust >= 0, gust_tau > 0, got {g}, {gust}, {gust_tau}")
    _check(isinstance(seed, (int, np.integer)), f"piloted_flight: seed must be an integer, got {seed!r}")
    outputs = tuple(outputs)
    channels = output_indices(outputs)
    std = _noise_levels(noise, outputs)
    n = int(round(duration / dt)) + 1
    time = dt * np.arange(n)
    if isinstance(excitation, Excitation):
        sticks, described = excitation(time), excitation.describe()
    else:
        sticks, described = np.asarray(excitation, dtype=np.float64), {"kind": "array"}
        _check(sticks.shape == (n, len(INPUT_NAMES)) and bool(np.all(np.isfinite(sticks))),
               f"piloted_flight: an excitation array must be finite with shape ({n}, 4), got {sticks.shape}")

    with jax.enable_x64(True):
        A, B = (np.asarray(M) for M in build_ab(theta, g))
        wind_in = -A[:, [STATE_NAMES.index(s) for s in _GUST_STATES]]
        disc = discretize(A, np.concatenate([B, wind_in], axis=1), dt)
        Ad, Bd, Ed = (np.asarray(M) for M in (disc.Ad, disc.B0[:, :4], disc.B0[:, 4:]))
        K, poles = pilot.gain(Ad, Bd, dt)
        key_gust, key_meas = jax.random.split(jax.random.key(seed))
        white = jax.random.normal(key_gust, (n, len(_GUST_STATES)), jnp.float64)
        rho = float(np.exp(-dt / gust_tau))
        if effect is None:
            states, applied = _fly(Ad, Bd, Ed, K, sticks, white, gust, rho, pilot.lag_samples(dt))
            clean = np.asarray(states)[:, channels]
        else:
            effect = np.asarray(effect, dtype=np.float64)
            _check(effect.shape == (size(outputs),) and bool(np.all(np.isfinite(effect))),
                   f"piloted_flight: effect must be {size(outputs)} finite values (jaxheli.effects.plant"
                   f" layout for {outputs}), got shape {effect.shape}")
            max_delay = float(np.max(np.abs(effect[layout(outputs)["delay"]]))) + dt
            plant = make_plant(theta, effect, dt, outputs, g=g, max_delay=max_delay)
            states, applied, clean = _fly_effect(plant, K, sticks, white, time, gust, rho, pilot.lag_samples(dt))
        meas_noise = jax.random.normal(key_meas, (n, len(outputs)), jnp.float64) * std[None, :]
        states, applied = np.asarray(states), np.asarray(applied)
        measured = np.asarray(clean) + np.asarray(meas_noise)
    if not np.all(np.isfinite(states)):
        raise ValueError("piloted_flight: the pilot lost control (non-finite states); lower the excitation "
                         "amplitudes or the gusts, or raise Pilot.max_stick")

    metadata = {
        "generator": "jaxheli.synth.piloted_flight",
        "truth": theta.tolist(),
        "g": float(g),
        "seed": int(seed),
        "dt": float(dt),
        "noise": dict(zip(outputs, std.tolist())),
        "gust": {"std": float(gust), "tau_s": float(gust_tau), "channels": list(_GUST_STATES)},
        "pilot": {
            "kind": "discrete LQR on the true state: an idealised pilot who knows the helicopter",
            "max_state": dict(pilot.max_state),
            "max_stick": pilot.max_stick,
            "delay_s": pilot.lag_samples(dt) * dt,
            "gain": K[:, : len(STATE_NAMES)].tolist(),
            "closed_loop_pole_magnitudes": np.sort(np.abs(poles)).tolist(),
            "open_loop_max_real_pole": float(np.max(np.linalg.eigvals(A).real)),
        },
        "excitation": described,
        "stick_rms": dict(zip(INPUT_NAMES, np.sqrt(np.mean(applied**2, axis=0)).tolist())),
        "saturated_fraction": float(np.mean(np.any(np.abs(applied) >= 1.0, axis=1))),
        "initial_state": [0.0] * len(STATE_NAMES),
        "effect": None if effect is None else effect.tolist(),
    }
    return FlightData(time, applied, measured, outputs, source=f"synthetic piloted flight (seed {seed})",
                      metadata=metadata)


DEFAULT_EXCITATION = Excitation("mixed", amplitude=(0.2, 0.2, 0.2, 0.2), unit=0.5, band=(0.2, 4.0))
"""Excitation of :func:`default_flight`."""


@functools.lru_cache(maxsize=1)
def default_flight() -> FlightData:
    """The flight shipped with the package: Table 2 truth, 80 s at 100 Hz, all four axes excited.

    :data:`DEFAULT_EXCITATION`: 3-2-1-1s (unit 0.5 s) then logarithmic sweeps (0.2-4 Hz), peak 0.2
    stick, on lat, lon, ped, col in turn; default pilot, default measurement noise, no gusts, seed 0.
    Generated on first use and cached; its arrays are read-only (copy before editing).
    """
    flight = piloted_flight(TABLE2, duration=80.0, dt=0.01, excitation=DEFAULT_EXCITATION, seed=0, noise=1.0)
    for array in (flight.time, flight.inputs, flight.outputs):
        array.flags.writeable = False
    return flight.replace(source="jaxheli default flight (synthetic, Table 2 truth)")


@functools.partial(jax.jit, static_argnames="lag")
def _fly(
    Ad: Array, Bd: Array, Ed: Array, K: Array, excitation: Array, white: Array, gust: float, rho: float,
    lag: int,
) -> tuple[Float[Array, "N 13"], Float[Array, "N 4"]]:
    """Closed-loop record as one scan: states ``x[k]`` and sticks applied over ``[t_k, t_k+1)``."""

    def step(carry, inputs):
        x, pending, wind = carry
        extra, w = inputs
        command = -K @ jnp.concatenate([x, pending.ravel()])
        applied = jnp.clip((pending[0] if lag else command) + extra, -1.0, 1.0)
        pending = jnp.concatenate([pending[1:], command[None]]) if lag else pending
        x_next = Ad @ x + Bd @ applied + Ed @ wind
        wind_next = rho * wind + jnp.sqrt(1.0 - rho**2) * gust * w
        return (x_next, pending, wind_next), (x, applied)

    init = (jnp.zeros(Ad.shape[0]), jnp.zeros((lag, Bd.shape[1])), jnp.zeros(Ed.shape[1]))
    _, (states, applied) = jax.lax.scan(step, init, (jnp.asarray(excitation), jnp.asarray(white)))
    return states, applied


@functools.partial(jax.jit, static_argnames="lag")
def _fly_effect(
    plant: Plant, K: Array, excitation: Array, white: Array, time: Array, gust: float, rho: float,
    lag: int,
) -> tuple[Float[Array, "N 13"], Float[Array, "N 4"], Float[Array, "N k"]]:
    """:func:`_fly` with the effect-augmented truth plant; also returns the clean sensor outputs."""

    def step(carry, inputs):
        x, pending, wind, history, servo, rotor = carry
        extra, w, t = inputs
        command = -K @ jnp.concatenate([x, pending.ravel()])
        applied = jnp.clip((pending[0] if lag else command) + extra, -1.0, 1.0)
        pending = jnp.concatenate([pending[1:], command[None]]) if lag else pending
        history, servo = plant.actuate(history, servo, applied)
        x_next, rotor = plant.advance(x, rotor, servo, wind)
        wind_next = rho * wind + jnp.sqrt(1.0 - rho**2) * gust * w
        return (x_next, pending, wind_next, history, servo, rotor), (x, applied, plant.measure(x, t))

    history, servo, rotor = plant.init_actuators()
    init = (jnp.zeros(plant.Ad.shape[0]), jnp.zeros((lag, plant.B.shape[1])), jnp.zeros(plant.E.shape[1]),
            history, servo, rotor)
    _, out = jax.lax.scan(step, init, (jnp.asarray(excitation), jnp.asarray(white), jnp.asarray(time)))
    return out


def _noise_levels(noise: float | Mapping[str, float], outputs: tuple[str, ...]) -> np.ndarray:
    """Per-output noise standard deviations from a scale on :data:`DEFAULT_NOISE` or an explicit map."""
    if isinstance(noise, Mapping):
        unknown = sorted(set(noise) - set(MEASURABLE))
        missing = [c for c in outputs if c not in noise]
        _check(not unknown and not missing,
               f"piloted_flight: noise map must name every output {outputs} (missing {missing}, "
               f"unknown {unknown})")
        std = np.array([float(noise[c]) for c in outputs])
    else:
        std = float(noise) * np.array([DEFAULT_NOISE[c] for c in outputs])
    _check(bool(np.all(np.isfinite(std)) and np.all(std >= 0)),
           f"piloted_flight: noise levels must be >= 0, got {noise}")
    return std


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise ValueError(message)
