"""The library's candidate unmodelled effects, one :class:`~jaxheli.effects.record.Effect` each, and their
registry :data:`EFFECTS`.

Each effect's parameters carry the largest magnitude that is physically plausible on a small helicopter,
generous on purpose (several times what the blind check injects): the box every fit stays in
(:func:`jaxheli.effects.registry.box`); a fit that ends on that bound has absorbed something other than the
effect (a mismatch the base model carries elsewhere), so it is flagged (:func:`jaxheli.effects.registry.at_bound`)
and never the verdict. Start values keep the fit away from kinks
such as ``|delay| = 0``, where the gradient vanishes. Every plant term is the identity at its no-effect value,
so effects that are absent cost nothing in accuracy.
"""

from __future__ import annotations

from collections.abc import Callable
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..model import INPUT_NAMES, N_INPUTS, STATE_NAMES
from .record import Dice, Draw, Effect, Group, Param, PlantView, Registry, Term

GYROS: tuple[str, ...] = ("p", "q", "r")
"""Output channels a scale-factor error acts on (gyros)."""

_PAIRS = (("u", "v"), ("p", "q"), ("phi", "theta"))
"""Output pairs a yaw misalignment rotates, each by its own angle: the velocity's by its frame's, the rates' by the
gyros' mount, the attitudes' by the attitude estimator's frame."""

_UNITS = {"u": "m/s", "v": "m/s", "w": "m/s", "p": "rad/s", "q": "rad/s", "r": "rad/s", "phi": "rad", "theta": "rad"}


def _per_axis(name: str, group: str, eta_order: int, unit: str, start: float, bound: float, term: Term,
              value: Callable[[np.random.Generator], float], tries: tuple[float, ...], together: bool = False
              ) -> Effect:
    """An effect with one parameter ``{group}_{axis}`` per stick axis, acting through ``|eta|``, further
    starts ``tries`` (on every axis at once too with ``together``), injected on the dice's random axis at
    ``value(rng)``."""

    def params(outputs: tuple[str, ...], at: Callable[[str, int], int]) -> tuple[Param, ...]:
        return tuple(Param(at(group, i), f"{group}_{a}", unit, a, start, True, bound, tries=tries, together=together)
                     for i, a in enumerate(INPUT_NAMES))

    def inject(dice: Dice) -> Draw:
        param = f"{group}_{INPUT_NAMES[dice.axis]}"
        return Draw({param: value(dice.rng)}, param)

    return Effect(name, (Group(group, N_INPUTS),), eta_order, params, (term,), inject)


def _delay_history(plant: PlantView) -> Float[Array, "D 4"]:
    return jnp.zeros((plant.max_delay + 2, N_INPUTS))


def _delay(plant: PlantView, history: Float[Array, "D 4"], sticks: Float[Array, "4"], servo: Float[Array, "4"]
           ) -> tuple[Float[Array, "D 4"], Float[Array, "4"]]:
    """Transport delay of ``|delay|`` s: linear interpolation of the held sticks (``history``, newest first)."""
    history = jnp.concatenate([sticks[None, :], history[:-1]], axis=0)
    d = jnp.clip(jnp.abs(plant.group("delay")) / plant.dt, 0.0, float(plant.max_delay))
    i0 = jnp.clip(jnp.floor(d), 0, plant.max_delay).astype(jnp.int32)
    f = d - i0
    axes = jnp.arange(N_INPUTS)
    return history, (1.0 - f) * history[i0, axes] + f * history[i0 + 1, axes]


INPUT_DELAY = _per_axis("input_delay", "delay", eta_order=0, unit="s", start=0.01, bound=0.5,
                        term=Term("command", _delay, init=_delay_history), value=lambda rng: rng.uniform(0.04, 0.12),
                        tries=(0.15,))
"""Transport delay per stick axis (s; servo and transport delays are 20-150 ms, plausible up to 0.5 s; a
further start at 150 ms). Injected: 40-120 ms on one random axis."""


def _lag(plant: PlantView, state: None, sticks: Float[Array, "4"], servo: Float[Array, "4"]
         ) -> tuple[None, Float[Array, "4"]]:
    """Servo lag of time constant ``|lag|`` s, backward Euler from the servo position ``servo``."""
    tau = jnp.abs(plant.group("lag"))
    a = tau / (tau + plant.dt)
    return state, a * servo + (1.0 - a) * sticks


ACTUATOR_LAG = _per_axis("actuator_lag", "lag", eta_order=1, unit="s", start=0.01, bound=0.5,
                         term=Term("servo", _lag), value=lambda rng: rng.uniform(0.05, 0.15), tries=(0.2,))
"""First-order servo lag per stick axis (s; rotor lags ~0.1 s, plausible up to 0.5 s; a further start at
200 ms). Injected: 50-150 ms on one random axis."""


_BIAS_BOUND = {"m/s": 3.0, "rad/s": 0.5, "rad": 0.35}
"""Largest plausible sensor bias per unit: 3 m/s (a GPS/airspeed offset), 0.5 rad/s (an uncalibrated gyro),
0.35 rad (20 deg of attitude)."""

_DRIFT_TIME = 10.0
"""A plausible drift reaches the plausible bias in no less than this many seconds."""

_NO_WALK = ("m/s",)
"""Units of the channels whose bias does not walk: velocities (satellite-navigation velocity has no bias
instability, as gyros and the attitudes integrated from them have), and within a restart segment a walking
velocity bias and a slow wind look alike (the bias candidate would take the wind's share through the velocity
channels); their walk slots stay 0."""

_WALK_START = 0.003
"""Start of each channel's walk intensity, as a fraction of its bound: away from ``|walk| = 0``, where the filter's
bias gain and its gradient vanish."""

_REVERT_BOUND = 2.0
"""Fastest plausible reversion of a wandering bias to its line (1/s): a correlation time of 0.5 s or longer (a
warming sensor's wander; faster wander is measurement noise)."""

_REVERT_START = 0.02
"""Start of the walk's reversion rate (1/s): a correlation time of 50 s, a random walk within any restart segment,
away from the kink at ``|rate| = 0``."""

_REVERT_TRY = 0.5
"""Further start of the reversion rate (1/s): a correlation time of 2 s, a wander that a fit from a random walk does
not reach."""


def _channel_params(outputs: tuple[str, ...], at: Callable[[str, int], int]) -> tuple[Param, ...]:
    units = [_UNITS.get(c, "-") for c in outputs]
    bounds = [_BIAS_BOUND.get(u, 1.0) for u in units]
    bias = tuple(Param(at("bias", i), f"bias_{c}", u, c, 0.0, False, b)
                 for i, (c, u, b) in enumerate(zip(outputs, units, bounds)))
    drift = tuple(Param(at("drift", i), f"drift_{c}", f"{u}/s", c, 0.0, False, b / _DRIFT_TIME)
                  for i, (c, u, b) in enumerate(zip(outputs, units, bounds)))
    walk_bounds = [b / np.sqrt(_DRIFT_TIME) for b in bounds]
    walk = tuple(Param(at("walk", i), f"walk_{c}", f"{u}/s^0.5", c, _WALK_START * w, True, w)
                 for i, (c, u, w) in enumerate(zip(outputs, units, walk_bounds)) if u not in _NO_WALK)
    walking = ",".join(c for c, u in zip(outputs, units) if u not in _NO_WALK)
    revert = (Param(at("revert", 0), "reversion", "1/s", walking, _REVERT_START, True, _REVERT_BOUND, shape=True,
                    tries=(_REVERT_TRY,)),) if walk else ()
    return bias + drift + walk + revert


def _offset(plant: PlantView, y: Float[Array, "k"], t: Float[Array, ""]) -> Float[Array, "k"]:
    return y + plant.group("bias") + plant.group("drift") * t


def _remove_offset(plant: PlantView, y: Float[Array, "N k"], t: Float[Array, "N"]) -> Float[Array, "N k"]:
    return y - plant.group("bias")[None, :] - t[:, None] * plant.group("drift")[None, :]


def _inject_bias_drift(dice: Dice) -> Draw:
    channel = dice.outputs[int(dice.rng.integers(len(dice.outputs)))]
    std = dice.noise[channel]
    drift = dice.rng.choice([-1.0, 1.0]) * dice.rng.uniform(2, 4) * std / dice.duration
    bias = dice.sign * dice.rng.uniform(2, 4) * std
    return Draw({f"drift_{channel}": drift, f"bias_{channel}": bias}, f"bias_{channel}")


OUTPUT_BIAS_DRIFT = Effect(
    name="output_bias_drift",
    groups=(Group("bias", None), Group("drift", None), Group("walk", None), Group("revert", 1)),
    eta_order=7,
    params=_channel_params,
    terms=(Term("reading", _offset, _remove_offset),),
    inject=_inject_bias_drift,
    filtered=True,
)
"""A constant bias and a linear drift on every output channel (the channel's units and per s; bias up to
3 m/s, 0.5 rad/s or 0.35 rad, drift up to that bias per 10 s): ``y + bias + drift t``, and a random walk of the bias
about that line on the rate and attitude channels (intensity ``walk``, the channel's unit per sqrt(s): the walk's std
grows as ``walk sqrt(t)``; up to the plausible bias in 10 s; none on velocities, :data:`_NO_WALK`), reverting to the
line at ``reversion`` (1/s, shared by the channels: ``b+ = e^(-rate dt) b + walk sqrt(dt) white``, a first-order
Gauss-Markov wander of correlation time ``1 / rate``, a random walk as the rate goes to 0; a shape parameter). The walk
has no plant term: it is a state of the restart filter (:func:`jaxheli.gap.kalman.gust_filter`), zero at each record's
start, re-estimated along it and reverting inside a segment, so a bias that wanders differently on the validation
flight than on the training flight is credited for its statistics rather than for the training flight's path, which no
fixed bias and drift can transfer. Injected: bias 2-4 noise standard deviations and a drift of as much again over the
flight, on one random channel (no walk: the independent simulator's bias walks it)."""


def _process_noise_params(outputs: tuple[str, ...], at: Callable[[str, int], int]) -> tuple[Param, ...]:
    return (Param(at("gust", 0), "gust_std", "m/s", "u,v,w", 0.3, True, 5.0),
            Param(at("gust", 1), "gust_tau", "s", "u,v,w", 1.0, True, 10.0, shape=True, tries=(3.0,)),
            Param(at("gust", 2), "state_noise_cut", "ln", "u,v,w", 1.0, True, 10.0, shape=True, nuisance=True))


def _inject_gusts(dice: Dice) -> Draw:
    gust, gust_tau = dice.rng.uniform(0.3, 0.8), dice.rng.uniform(0.5, 2.0)
    return Draw({"gust_tau": gust_tau, "gust_std": gust}, "gust_std", gust, gust_tau)


PROCESS_NOISE = Effect(
    name="process_noise",
    groups=(Group("gust", 3, (0.0, 1.0, 0.0)),),
    eta_order=5,
    params=_process_noise_params,
    terms=(),
    inject=_inject_gusts,
    filtered=True,
)
"""First-order Gauss-Markov wind on u, v, w: std (m/s, plausible up to 5), correlation time (s, up to 10; 1 s at no
effect) and a cut ``c`` of the restart filter's white state noise (``track`` to ``track e^-|c|``, ``|c|`` up to 10:
the filter-error method estimates the whole process-noise model; once the gusts explain the wind, the filter need
not follow the sensors as closely as at the base model's tuned level). The cut is a nuisance: every fit frees it, so
the effect is credited for the gusts alone, not for re-tuning the filter. A further start at a correlation time of 3 s,
kept when its training sum of squares is lower: from 1 s alone the joint fit can leave both gust parameters at their
starts. No plant term: the wind enters every plant
through ``E``; :func:`jaxheli.gap.kalman.gust_filter` reads this group. Injected: a flight in gusts of 0.3-0.8 m/s
with 0.5-2 s correlation."""


def _drag_params(outputs: tuple[str, ...], at: Callable[[str, int], int]) -> tuple[Param, ...]:
    return (Param(at("drag", 0), "Xuu", "1/m", "u", 0.0, False, 10.0, tries=(-3.0,), together=True),
            Param(at("drag", 1), "Yvv", "1/m", "v", 0.0, False, 10.0, tries=(-3.0,), together=True),
            Param(at("drag", 2), "wind_u", "m/s", "u", 0.0, False, 5.0, shape=True),
            Param(at("drag", 3), "wind_v", "m/s", "v", 0.0, False, 5.0, shape=True))


def _drag(plant: PlantView, state: None, x: Float[Array, "13"], applied: Float[Array, "4"]
          ) -> tuple[None, Float[Array, "13"]]:
    """``Xuu a|a| - Xuu a0|a0|`` on ``u'`` with airspeed ``a = u - wind_u`` (``a0 = -wind_u`` at trim), and the
    same with ``Yvv`` and ``wind_v`` on ``v'``."""
    xuu, yvv, wind_u, wind_v = plant.group("drag")
    iu, iv = STATE_NAMES.index("u"), STATE_NAMES.index("v")

    def quadratic(k: Float[Array, ""], speed: Float[Array, ""], wind: Float[Array, ""]) -> Float[Array, ""]:
        air = speed - wind
        return k * (air * jnp.abs(air) + wind * jnp.abs(wind))

    return state, jnp.zeros_like(x).at[iu].set(quadratic(xuu, x[iu], wind_u)).at[iv].set(quadratic(yvv, x[iv], wind_v))


def _inject_drag(dice: Dice) -> Draw:
    yvv = -dice.rng.uniform(1.0, 3.0)
    return Draw({"Yvv": yvv, "Xuu": -dice.rng.uniform(1.0, 3.0)}, "Xuu")


QUADRATIC_DRAG = Effect(
    name="quadratic_drag",
    groups=(Group("drag", 4),),
    eta_order=3,
    params=_drag_params,
    terms=(Term("airframe", _drag),),
    inject=_inject_drag,
)
"""Quadratic drag on the airspeed along u and v in a steady wind, less its trim value (1/m, plausible up to 10; further
starts at -3 on both and on each; wind along body u and v in m/s, plausible up to 5, shape parameters): a drag acts on
the air's speed past the rotor, and in a hover in wind the trim sits on the slope of the drag curve, so about that trim
the drag is the even ``-Xuu u^2 sign(wind)`` beside a linear part the base model's ``Xu`` shares, which the odd
``Xuu u|u|`` of still air cannot represent. Injected: 1-3 1/m on both, in still air."""


def _saturate(plant: PlantView, state: None, sticks: Float[Array, "4"], servo: Float[Array, "4"]
              ) -> tuple[None, Float[Array, "4"]]:
    """``u / sqrt(1 + k u^2)``: a smooth limit at ``1 / sqrt(k)`` stick, ``k = |sat|``."""
    return state, sticks / jnp.sqrt(1.0 + jnp.abs(plant.group("sat")) * sticks**2)


CONTROL_SATURATION = _per_axis("control_saturation", "sat", eta_order=2, unit="1/stick^2", start=1.0,
                               bound=400.0, term=Term("command", _saturate),
                               value=lambda rng: rng.uniform(0.15, 0.3) ** -2, tries=(25.0, 90.0), together=True)
"""Saturation of the delayed sticks per axis (1/stick^2, plausible up to 400: a limit no tighter than 0.05 of full
stick, so that a travel stop at 0.08 stick is fitted inside the bound; further starts at 25 and 90, limits at 0.2 and
0.105 stick, on all axes and on each: from 25 alone, the diagnosis's few LM steps leave a tight limit near its
start). Injected: a limit at 0.15-0.3 stick on one random axis."""


def _rotor_params(outputs: tuple[str, ...], at: Callable[[str, int], int]) -> tuple[Param, ...]:
    return (Param(at("rotor", 0), "rotor_gain", "rad/s^2 per stick", "col->r", 0.1, False, 50.0),
            Param(at("rotor", 1), "rotor_tau", "s", "col->r", 0.5, True, 3.0, shape=True))


def _rotor_speed(plant: PlantView) -> Float[Array, ""]:
    return jnp.zeros(())


def _rotor(plant: PlantView, rotor: Float[Array, ""], x: Float[Array, "13"], applied: Float[Array, "4"]
           ) -> tuple[Float[Array, ""], Float[Array, "13"]]:
    """Rotor-speed state, a backward-Euler lag of the collective, driving the yaw acceleration."""
    gain, tau = plant.group("rotor")
    tau = jnp.abs(tau) + 1e-6
    rotor = (tau * rotor + plant.dt * gain * applied[INPUT_NAMES.index("col")]) / (tau + plant.dt)
    return rotor, jnp.zeros_like(x).at[STATE_NAMES.index("r")].set(rotor)


def _inject_rotor(dice: Dice) -> Draw:
    tau = dice.rng.uniform(0.3, 1.0)
    return Draw({"rotor_tau": tau, "rotor_gain": dice.sign * dice.rng.uniform(2.0, 5.0)}, "rotor_gain")


ROTOR_SPEED_COUPLING = Effect(
    name="rotor_speed_coupling",
    groups=(Group("rotor", 2, (0.0, 0.5)),),
    eta_order=4,
    params=_rotor_params,
    terms=(Term("airframe", _rotor, init=_rotor_speed),),
    inject=_inject_rotor,
)
"""Collective to yaw through the rotor speed: gain (rad/s^2 per stick, plausible up to 50) and time
constant (s, up to 3; 0.5 s at no effect). Injected: 2-5 rad/s^2 per stick with a 0.3-1 s time constant."""


def _misalignment_params(outputs: tuple[str, ...], at: Callable[[str, int], int]) -> tuple[Param, ...]:
    return (Param(at("mis", 0), "yaw_misalignment", "rad", "p-q", 0.0, False, 0.35, tries=(0.1, -0.1)),
            Param(at("mis", 1), "velocity_yaw", "rad", "u-v", 0.0, False, 0.35),
            Param(at("mis", 2), "attitude_yaw", "rad", "phi-theta", 0.0, False, 0.35),
            *(Param(at("mis", 3 + i), f"scale_{c}", "fraction", c, 0.0, False, 0.5) for i, c in enumerate(GYROS)
              if c in outputs))


def _sensor_matrix(plant: PlantView) -> Float[Array, "k k"]:
    """``M``: scale factors on p, q, r, then a yaw rotation of the (u, v) pair by the velocity frame's angle, of the
    (p, q) pair by the gyros' mount and of the (phi, theta) pair by the attitude estimator's frame."""
    eps, eps_v, eps_a, *scale = plant.group("mis")
    outputs = plant.outputs
    k = len(outputs)
    diag = jnp.ones(k)
    for name, s in zip(GYROS, scale):
        if name in outputs:
            diag = diag.at[outputs.index(name)].add(s)
    R = jnp.eye(k)
    for (a, b), angle in zip(_PAIRS, (eps_v, eps, eps_a)):
        if a in outputs and b in outputs:
            i, j = outputs.index(a), outputs.index(b)
            c, s = jnp.cos(angle), jnp.sin(angle)
            R = R.at[i, i].set(c).at[i, j].set(s).at[j, i].set(-s).at[j, j].set(c)
    return R * diag[None, :]


def _mount(plant: PlantView, y: Float[Array, "k"], t: Float[Array, ""]) -> Float[Array, "k"]:
    return _sensor_matrix(plant) @ y


def _unmount(plant: PlantView, y: Float[Array, "N k"], t: Float[Array, "N"]) -> Float[Array, "N k"]:
    return jnp.linalg.solve(_sensor_matrix(plant), y.T).T


def _inject_misalignment(dice: Dice) -> Draw:
    scale = dice.rng.choice([-1, 1]) * dice.rng.uniform(0.03, 0.08)
    gyros = [c for c in GYROS if c in dice.outputs]
    gyro = gyros[int(dice.rng.integers(len(gyros)))]
    yaw = dice.sign * np.deg2rad(dice.rng.uniform(2.0, 5.0))
    return Draw({f"scale_{gyro}": scale, "yaw_misalignment": yaw, "velocity_yaw": yaw, "attitude_yaw": yaw},
                "yaw_misalignment")


SENSOR_MISALIGNMENT = Effect(
    name="sensor_misalignment",
    groups=(Group("mis", 3 + len(GYROS)),),
    eta_order=6,
    params=_misalignment_params,
    terms=(Term("mounting", _mount, _unmount),),
    inject=_inject_misalignment,
)
"""A yaw mounting misalignment of the IMU (rad, plausible up to 0.35 = 20 deg; further starts at +-0.1: the base
model's cross derivatives mimic a small rotation of p and q, so a joint fit from no misalignment stops short), the
velocity frame's own yaw (rad, up to 0.35: satellite-navigation velocity is resolved into body axes through the
heading estimate, not through the IMU's mount), the attitude estimator's own yaw (rad, up to 0.35: an estimator
aligned to the airframe reads true roll and pitch from misaligned gyros, one that runs in the IMU's frame reads them
rotated as the rates) and scale-factor errors of the gyros present (fractions, up to 0.5). Injected: 2-5 deg on all
three with a 3-8 % scale error on one random gyro."""

EFFECTS = Registry((INPUT_DELAY, ACTUATOR_LAG, OUTPUT_BIAS_DRIFT, PROCESS_NOISE, QUADRATIC_DRAG, CONTROL_SATURATION,
                    ROTOR_SPEED_COUPLING, SENSOR_MISALIGNMENT))
"""The library's effects, in their stable order."""
