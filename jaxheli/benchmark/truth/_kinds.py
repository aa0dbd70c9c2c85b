"""The kinds of effect this simulator injects, how each is drawn, and which catalogue candidates count as naming it.

:data:`KIND_CANDIDATES` lists, per kind, the candidates (of ``jaxheli.effects.catalogue``) a right diagnosis may name;
a drawn kind also states the candidate parameters its physics shares with those forms (:class:`Injected`), so a
magnitude error can be computed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

import numpy as np

from ._airframe import Drag, Governor
from ._flight import Effects
from ._sensors import BiasWalk, Imu, Quantiser, Vibration
from ._servo import Servo
from ._turbulence import Dryden

AXES: tuple[str, ...] = ("lat", "lon", "ped", "col")

KIND_CANDIDATES: dict[str, tuple[str, ...]] = {
    "servo_limits": ("control_saturation", "actuator_lag"),
    "logger_delay": ("input_delay",),
    "servo_dynamics": ("actuator_lag", "input_delay"),
    "dryden": ("process_noise",),
    "drag": ("quadratic_drag",),
    "imu_misalignment": ("sensor_misalignment",),
    "bias_walk": ("output_bias_drift",),
    "rotor_droop": ("rotor_speed_coupling",),
    "quantisation": ("none",),
    "vibration": ("none",),
    "two_at_once": (),
    "none": ("none",),
}
"""Candidates that count as right per injected kind: a travel stop is a saturation (its rate limit acts as a lag
on large steps); a link delay in whole frames an input delay; a second-order servo a lag or, at low frequency, a
delay; Dryden turbulence process noise; drag against the wind quadratic drag; a rotated gyro triad and velocity frame a
mounting misalignment; a wandering bias a bias with drift and walk; governor droop the rotor-speed coupling; quantisation and
an aliased vibration line none (no candidate has their form). ``two_at_once``: either part's candidates."""

SINGLE: tuple[str, ...] = ("servo_limits", "logger_delay", "servo_dynamics", "dryden", "drag", "imu_misalignment",
                           "bias_walk", "rotor_droop")
"""Kinds with a candidate of their own, the parts ``two_at_once`` draws from."""

KINDS: tuple[str, ...] = tuple(KIND_CANDIDATES)


@dataclasses.dataclass(frozen=True)
class Injected:
    """A drawn kind: its ``effects``, the ``parts`` it combines (itself unless ``two_at_once``), the ``candidates``
    that count as right and ``shared``: per candidate, the values its parameters take for this physics (the first
    candidate's first parameter is the magnitude compared)."""

    kind: str
    effects: Effects
    parts: tuple[str, ...]
    candidates: tuple[str, ...]
    shared: dict[str, dict[str, float]]


@dataclasses.dataclass(frozen=True)
class Dice:
    """What a draw may use: ``rng``, ``strength`` (a multiple of the size), per-channel ``noise`` std, the flight's
    ``duration`` and logger ``dt`` (s), its ``outputs``."""

    rng: np.random.Generator
    strength: float
    noise: Mapping[str, float]
    duration: float
    dt: float
    outputs: tuple[str, ...]

    def sign(self) -> float:
        """A random sign."""
        return float(self.rng.choice([-1.0, 1.0]))


def _on_axis(axis: int, value: float, default: float) -> tuple[float, ...]:
    """Per-axis values: ``value`` on ``axis``, ``default`` on the others."""
    return tuple(value if i == axis else default for i in range(len(AXES)))


def _servo_limits(d: Dice) -> tuple[Effects, dict]:
    """Travel stops at 0.1-0.2 stick and a 1-3 stick/s rate limit on one axis (tighter with strength); shared: the
    saturation ``1 / limit^2``."""
    axis = int(d.rng.integers(len(AXES)))
    limit = max(0.06, d.rng.uniform(0.1, 0.2) / np.sqrt(d.strength))
    rate = max(0.3, d.rng.uniform(1.0, 3.0) / d.strength)
    servo = Servo(limit=_on_axis(axis, limit, np.inf), rate=_on_axis(axis, rate, np.inf))
    return Effects(servo=servo), {"control_saturation": {f"sat_{AXES[axis]}": limit**-2}}


def _logger_delay(d: Dice) -> tuple[Effects, dict]:
    """A radio-link latency of whole logger frames on every axis: 40-100 ms times strength, at least one frame, at
    most 0.2 s; shared: the delay."""
    frames = int(np.clip(round(d.rng.uniform(0.04, 0.1) * d.strength / d.dt), 1, max(1, int(0.2 / d.dt))))
    delay = frames * d.dt
    return Effects(servo=Servo(delay=(frames,) * len(AXES))), {"input_delay": {f"delay_{a}": delay for a in AXES}}


def _servo_dynamics(d: Dice) -> tuple[Effects, dict]:
    """A second-order servo on one axis, ``wn`` 12-25 rad/s over strength (at least 6), ``zeta`` 0.5-0.9; shared: the
    low-frequency equivalent lag and delay ``2 zeta / wn`` (first moment of the impulse response)."""
    axis = int(d.rng.integers(len(AXES)))
    wn, zeta = max(6.0, d.rng.uniform(12.0, 25.0) / d.strength), d.rng.uniform(0.5, 0.9)
    servo = Servo(wn=_on_axis(axis, wn, np.inf), zeta=_on_axis(axis, zeta, 0.7))
    tau = 2.0 * zeta / wn
    return Effects(servo=servo), {"actuator_lag": {f"lag_{AXES[axis]}": tau},
                                  "input_delay": {f"delay_{AXES[axis]}": tau}}


def _dryden(d: Dice) -> tuple[Effects, dict]:
    """Dryden turbulence, ``w20`` 2-4 m/s times strength (at most 8), 2-6 m above ground, carried by a 2-5 m/s wind
    past a 1.5 m rotor; shared: ``gust_std`` the horizontal ``sigma_u``, ``gust_tau`` its ``L_u / V``."""
    dryden = Dryden(min(8.0, d.rng.uniform(2.0, 4.0) * d.strength), d.rng.uniform(2.0, 6.0),
                    d.rng.uniform(2.0, 5.0), 1.5)
    return Effects(turbulence=dryden), {"process_noise": {"gust_std": dryden.sigmas()[0],
                                                          "gust_tau": dryden.scales()[0] / dryden.speed}}


def _drag(d: Dice) -> tuple[Effects, dict]:
    """``X_uu``, ``Y_vv`` of -1 to -3 1/m times strength (at least -9) against a steady wind of up to 1 m/s on u
    and v; shared: both and the wind."""
    xuu, yvv = (max(-9.0, -d.rng.uniform(1.0, 3.0) * d.strength) for _ in range(2))
    wind = d.rng.uniform(-1.0, 1.0, 2)
    drag = Drag(xuu, yvv, (float(wind[0]), float(wind[1])))
    return Effects(drag=drag), {"quadratic_drag": {"Xuu": xuu, "Yvv": yvv, "wind_u": drag.wind[0],
                                                   "wind_v": drag.wind[1]}}


def _imu_misalignment(d: Dice) -> tuple[Effects, dict]:
    """A gyro triad at 2-5 deg of yaw times strength (at most 15 deg), tilted up to 1 deg, with 3-8 % scale errors
    on p and q, and a velocity frame at 0.5-1.5 times that yaw; shared: both yaws and the scales."""
    yaw = d.sign() * np.deg2rad(min(15.0, d.rng.uniform(2.0, 5.0) * d.strength))
    scale = (d.sign() * d.rng.uniform(0.03, 0.08), d.sign() * d.rng.uniform(0.03, 0.08), 0.0)
    imu = Imu(yaw, tuple(np.deg2rad(d.rng.uniform(-1.0, 1.0, 2))), scale, yaw * d.rng.uniform(0.5, 1.5))
    return Effects(imu=imu), {"sensor_misalignment": {"yaw_misalignment": yaw, "velocity_yaw": imu.velocity_yaw,
                                                      "scale_p": scale[0], "scale_q": scale[1]}}


def _bias_walk(d: Dice) -> tuple[Effects, dict]:
    """A turn-on bias of 2-4 noise std times strength on one rate or attitude channel, wandering by as much again
    (std) over the flight; shared: the turn-on bias and the walk's intensity (as the candidate's ``walk``, its square
    root: unit per sqrt(s)), each flight walking its own path."""
    channel = str(d.rng.choice([c for c in ("p", "q", "r", "phi", "theta") if c in d.outputs]))
    sigma = d.noise[channel] * d.strength
    walk = BiasWalk(channel, d.sign() * d.rng.uniform(2.0, 4.0) * sigma,
                    (d.rng.uniform(2.0, 4.0) * sigma) ** 2 / d.duration)
    return Effects(bias=walk), {"output_bias_drift": {f"bias_{channel}": walk.start,
                                                      f"walk_{channel}": float(np.sqrt(walk.intensity))}}


def _rotor_droop(d: Dice) -> tuple[Effects, dict]:
    """Droop of 3-8 % per stick of collective times strength (at most 30 %) under a 0.3-1 s governor, a yaw
    authority of 40-80 rad/s^2 per unit speed change; shared: ``rotor_gain = -yaw droop`` (the steady yaw
    acceleration per stick) and ``rotor_tau`` the governor's time constant."""
    governor = Governor(min(0.3, d.rng.uniform(0.03, 0.08) * d.strength), d.rng.uniform(0.3, 1.0),
                        d.sign() * d.rng.uniform(40.0, 80.0))
    return Effects(governor=governor), {"rotor_speed_coupling": {"rotor_gain": -governor.yaw * governor.droop,
                                                                 "rotor_tau": governor.tau}}


def _quantisation(d: Dice) -> tuple[Effects, dict]:
    """An ADC step of 2-4 noise std times strength on every channel; nothing shared."""
    return Effects(quantiser=Quantiser({c: d.rng.uniform(2.0, 4.0) * d.strength * d.noise[c] for c in d.outputs})), {}


def _vibration(d: Dice) -> tuple[Effects, dict]:
    """A 21-29 Hz line of 1-3 gyro-noise std times strength on p and q; nothing shared."""
    gyro = [c for c in ("p", "q") if c in d.outputs]
    line = Vibration(d.rng.uniform(1.0, 3.0) * d.strength * d.noise[gyro[0]], d.rng.uniform(21.0, 29.0),
                     d.rng.uniform(0.0, 2.0 * np.pi), tuple(gyro))
    return Effects(vibration=line), {}


_DRAWS: dict[str, Callable[[Dice], tuple[Effects, dict]]] = {
    "servo_limits": _servo_limits, "logger_delay": _logger_delay, "servo_dynamics": _servo_dynamics,
    "dryden": _dryden, "drag": _drag, "imu_misalignment": _imu_misalignment, "bias_walk": _bias_walk,
    "rotor_droop": _rotor_droop, "quantisation": _quantisation, "vibration": _vibration,
}


def draw(kind: str, dice: Dice) -> Injected:
    """Draw ``kind`` (:data:`KINDS`) with ``dice``; ``two_at_once`` draws two different :data:`SINGLE` kinds and
    joins them (:func:`join`)."""
    if kind not in KIND_CANDIDATES:
        raise ValueError(f"truth simulator: unknown kind {kind!r}; kinds are {KINDS}")
    if kind == "none":
        return Injected(kind, Effects(), (), KIND_CANDIDATES[kind], {})
    if kind == "two_at_once":
        first, second = (draw(str(k), dice) for k in dice.rng.choice(SINGLE, 2, replace=False))
        return Injected(kind, join(first.effects, second.effects), first.parts + second.parts,
                        tuple(dict.fromkeys(first.candidates + second.candidates)),
                        first.shared | {k: v for k, v in second.shared.items() if k not in first.shared})
    effects, shared = _DRAWS[kind](dice)
    shared = {c: {p: float(v) for p, v in values.items()} for c, values in shared.items()}
    return Injected(kind, effects, (kind,), KIND_CANDIDATES[kind], shared)


def join(a: Effects, b: Effects) -> Effects:
    """Both ``a`` and ``b``: each absent part from the other, the servo chains axis by axis (the longer delay, the
    tighter limit and rate, the slower servo)."""
    parts = {f.name: getattr(a, f.name) if getattr(b, f.name) is None else getattr(b, f.name)
             for f in dataclasses.fields(Effects) if f.name != "servo"}
    sa, sb = a.servo, b.servo
    slower = [wa <= wb for wa, wb in zip(sa.wn, sb.wn)]
    servo = Servo(tuple(map(max, sa.delay, sb.delay)), tuple(map(min, sa.limit, sb.limit)),
                  tuple(map(min, sa.rate, sb.rate)), tuple(map(min, sa.wn, sb.wn)),
                  tuple(za if s else zb for s, za, zb in zip(slower, sa.zeta, sb.zeta)))
    return Effects(servo=servo, **parts)
