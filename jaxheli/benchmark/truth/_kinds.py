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
from ._sensors import BiasDrift, Imu, Quantiser, Vibration
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
    "bias_drift": ("output_bias_drift",),
    "rotor_droop": ("rotor_speed_coupling",),
    "quantisation": ("none",),
    "vibration": ("none",),
    "two_at_once": (),
    "none": ("none",),
}
"""Candidates that count as right per injected kind: a travel stop is a saturation (its rate limit acts as a lag
on large steps); a link's latency, jitter and lost frames an input delay; a second-order, rate-limited servo with
backlash a lag or, at low frequency, a delay; Dryden turbulence process noise; drag along the airspeed vector
quadratic drag; tilted, mis-scaled gyro and velocity mounts a mounting misalignment; a bias that settles and wanders
a bias with drift and walk; governor droop the rotor-speed coupling; quantisation and an aliased vibration line none
(no candidate has their form). ``two_at_once``: either part's candidates. No kind is drawn in a candidate's own
form, though the nearest candidate comes within the noise of those in :data:`IN_FAMILY`."""

IN_FAMILY: tuple[str, ...] = ("servo_limits", "drag")
"""Kinds whose nearest candidate reproduces the drawn effect within the sensor noise on some draws
(``benchmarks/truth_forms.py``): travel stops and a rate limit as the smooth saturation, at the sizes a 30-s
flight reaches, and drag along the airspeed as per-axis drag for some wind directions. Every other kind lies outside
its candidates' family (``tests/test_truth_forms.py``)."""

SINGLE: tuple[str, ...] = ("servo_limits", "logger_delay", "servo_dynamics", "dryden", "drag", "imu_misalignment",
                           "bias_drift", "rotor_droop")
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
    """A radio link on every axis: latency 40-100 ms times strength (at most 0.2 s, not a whole number of frames),
    jitter of std 0.2-0.5 frame, 2-8 % of frames lost; shared: the mean delay (latency, mean jitter, and half a
    frame per lost frame's share)."""
    latency = min(0.2, d.rng.uniform(0.04, 0.1) * d.strength)
    jitter, drop = d.rng.uniform(0.2, 0.5) * d.dt, d.rng.uniform(0.02, 0.08)
    delay = latency + jitter * np.sqrt(2.0 / np.pi) + 0.5 * drop * d.dt
    servo = Servo(delay=(latency,) * len(AXES), jitter=jitter, drop=drop)
    return Effects(servo=servo), {"input_delay": {f"delay_{a}": delay for a in AXES}}


def _servo_dynamics(d: Dice) -> tuple[Effects, dict]:
    """A second-order servo on one axis, ``wn`` 12-25 rad/s over strength (at least 6), ``zeta`` 0.5-0.9, its rate
    limited to 2-5 stick/s over strength (at least 1) and a backlash of 0.005-0.015 stick times strength (at most
    0.04); shared: the low-frequency equivalent lag and delay ``2 zeta / wn`` (first moment of the impulse
    response)."""
    axis = int(d.rng.integers(len(AXES)))
    wn, zeta = max(6.0, d.rng.uniform(12.0, 25.0) / d.strength), d.rng.uniform(0.5, 0.9)
    rate = max(1.0, d.rng.uniform(2.0, 5.0) / d.strength)
    backlash = min(0.04, d.rng.uniform(0.005, 0.015) * d.strength)
    servo = Servo(wn=_on_axis(axis, wn, np.inf), zeta=_on_axis(axis, zeta, 0.7), rate=_on_axis(axis, rate, np.inf),
                  backlash=_on_axis(axis, backlash, 0.0))
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
    """``X_uu``, ``Y_vv`` of -1 to -3 1/m times strength (at least -9) along the airspeed in a steady wind of 1.5-3
    m/s from 20-70 deg off a body axis (so that the drag couples u and v, which per-axis drag cannot); shared: both
    and the wind."""
    xuu, yvv = (max(-9.0, -d.rng.uniform(1.0, 3.0) * d.strength) for _ in range(2))
    speed = d.rng.uniform(1.5, 3.0)
    heading = np.deg2rad(d.rng.uniform(20.0, 70.0) + 90.0 * d.rng.integers(4))
    drag = Drag(xuu, yvv, (float(speed * np.cos(heading)), float(speed * np.sin(heading))))
    return Effects(drag=drag), {"quadratic_drag": {"Xuu": xuu, "Yvv": yvv, "wind_u": drag.wind[0],
                                                   "wind_v": drag.wind[1]}}


def _imu_misalignment(d: Dice) -> tuple[Effects, dict]:
    """A gyro triad at 2-5 deg of yaw times strength (at most 15 deg), tilted 4-8 deg in roll and pitch, with 3-8 %
    scale errors on p and q and up to 3 % on r; a velocity sensor at 0.5-1.5 times that yaw, tilted 4-8 deg, with
    4-8 % scale errors on u and v; shared: both yaws and the gyro scales."""
    yaw = d.sign() * np.deg2rad(min(15.0, d.rng.uniform(2.0, 5.0) * d.strength))
    scale = (d.sign() * d.rng.uniform(0.03, 0.08), d.sign() * d.rng.uniform(0.03, 0.08), d.rng.uniform(-0.03, 0.03))

    def tilt() -> tuple[float, float]:
        return tuple(float(d.sign() * np.deg2rad(d.rng.uniform(4.0, 8.0))) for _ in range(2))

    imu = Imu(yaw, tilt(), scale, yaw * d.rng.uniform(0.5, 1.5), tilt(),
              tuple(float(d.sign() * d.rng.uniform(0.04, 0.08)) for _ in range(2)))
    return Effects(imu=imu), {"sensor_misalignment": {"yaw_misalignment": yaw, "velocity_yaw": imu.velocity_yaw,
                                                      "scale_p": scale[0], "scale_q": scale[1]}}


def _bias_drift(d: Dice) -> tuple[Effects, dict]:
    """On one rate or attitude channel, a switch-on bias of 2-4 noise std times strength, settling by 2-4 std more
    over 8-25 s, and a Gauss-Markov wander of 2.5-4 std with a correlation time of 1-4 s, each flight its own
    path; shared: the switch-on bias."""
    channel = str(d.rng.choice([c for c in ("p", "q", "r", "phi", "theta") if c in d.outputs]))
    sigma = d.noise[channel] * d.strength
    drift = BiasDrift(channel, d.sign() * d.rng.uniform(2.0, 4.0) * sigma, d.sign() * d.rng.uniform(2.0, 4.0) * sigma,
                      d.rng.uniform(8.0, 25.0), d.rng.uniform(2.5, 4.0) * sigma, d.rng.uniform(1.0, 4.0))
    return Effects(bias=drift), {"output_bias_drift": {f"bias_{channel}": drift.start}}


def _rotor_droop(d: Dice) -> tuple[Effects, dict]:
    """Droop of 3-8 % per stick of collective times strength (at most 30 %) through a rotor of 0.3-1 s, restored
    by a governor's integral action at 2-5 rad/s, a yaw authority of 40-80 rad/s^2 per unit speed change; shared:
    ``rotor_gain = -yaw droop`` and ``rotor_tau`` the rotor's time constant (the onset of the droop, which the
    candidate's first-order coupling holds where the governor restores the speed)."""
    governor = Governor(min(0.3, d.rng.uniform(0.03, 0.08) * d.strength), d.rng.uniform(0.3, 1.0),
                        d.sign() * d.rng.uniform(40.0, 80.0), d.rng.uniform(2.0, 5.0) ** 2)
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
    "dryden": _dryden, "drag": _drag, "imu_misalignment": _imu_misalignment, "bias_drift": _bias_drift,
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
    """Both ``a`` and ``b``: each absent part from the other, the servo chains axis by axis (the longer delay,
    jitter and loss, the tighter limit and rate, the slower servo, the wider backlash)."""
    parts = {f.name: getattr(a, f.name) if getattr(b, f.name) is None else getattr(b, f.name)
             for f in dataclasses.fields(Effects) if f.name != "servo"}
    sa, sb = a.servo, b.servo
    slower = [wa <= wb for wa, wb in zip(sa.wn, sb.wn)]
    servo = Servo(tuple(map(max, sa.delay, sb.delay)), max(sa.jitter, sb.jitter), max(sa.drop, sb.drop),
                  tuple(map(min, sa.limit, sb.limit)), tuple(map(min, sa.rate, sb.rate)),
                  tuple(map(min, sa.wn, sb.wn)), tuple(za if s else zb for s, za, zb in zip(slower, sa.zeta, sb.zeta)),
                  tuple(map(max, sa.backlash, sb.backlash)))
    return Effects(servo=servo, **parts)
