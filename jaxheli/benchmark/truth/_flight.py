"""The closed-loop flight: the hover model at a fine internal step under this package's pilot, with the effects.

Per logger frame the pilot sets the sticks from the true state and the logger records sticks and sensor
readings; between frames the servo chain, the airframe forces and the turbulence advance ``substeps`` internal
steps, the linear part exactly (one matrix exponential), the extra accelerations held over each step.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._airframe import Drag, Governor
from ._hover import GRAVITY, STICKS, gust_matrix, hover_model, zoh
from ._pilot import excitation, lqr_gain
from ._sensors import BiasDrift, Imu, Quantiser, Vibration, read
from ._servo import Servo, ServoState
from ._turbulence import Dryden

OUTPUTS: tuple[str, ...] = ("u", "v", "p", "q", "phi", "theta", "w", "r")
"""Logged channels (m/s, rad/s, rad), the library's synthetic flights' default."""

NOISE: dict[str, float] = dict(u=0.05, v=0.05, w=0.05, p=0.015, q=0.015, r=0.015, phi=0.005, theta=0.005)
"""Sensor-noise std per channel at noise level 1 (m/s, rad/s, rad): GPS velocity, MEMS gyros, an attitude filter."""

_COL = STICKS.index("col")


@dataclasses.dataclass(frozen=True)
class Effects:
    """What this simulator adds to the hover model; ``None`` (and the default, ideal servo) is absent."""

    servo: Servo = Servo()
    turbulence: Dryden | None = None
    drag: Drag | None = None
    governor: Governor | None = None
    imu: Imu | None = None
    bias: BiasDrift | None = None
    vibration: Vibration | None = None
    quantiser: Quantiser | None = None


@dataclasses.dataclass(frozen=True)
class Record:
    """A logged flight: frame ``time`` [N] (s), the pilot's ``sticks`` [N, 4], the true ``states`` [N, 13], the
    noise-free readings ``clean`` [N, k] (every effect, no white noise) and the ``measured`` ones."""

    time: np.ndarray
    sticks: np.ndarray
    states: np.ndarray
    clean: np.ndarray
    measured: np.ndarray


def fly(theta: np.ndarray, effects: Effects, *, style: str, duration: float, dt: float, seed: int,
        noise: np.ndarray, outputs: tuple[str, ...] = OUTPUTS, substeps: int = 10, g: float = GRAVITY) -> Record:
    """Fly the 40 parameters ``theta`` for ``duration`` s with a logger of sample time ``dt`` (s) and ``substeps``
    internal steps per frame, the pilot's excitation ``style`` (:func:`~._pilot.excitation`), ``effects``, white
    sensor noise of std ``noise`` per output (channel units). ``seed`` fixes the excitation, the turbulence, the
    bias drift, the noise and the link's jitter and losses, each from a stream of its own (so a flight without an
    effect meets the same sticks)."""
    streams = [np.random.default_rng([seed, k]) for k in range(5)]
    A, B = hover_model(theta, g)
    E = gust_matrix(A)
    h = dt / substeps
    Ad, G = zoh(A, np.eye(len(A)), h)
    K = lqr_gain(A, B, dt)
    n = int(round(duration / dt)) + 1
    time = dt * np.arange(n)
    extra = excitation(style, time, streams[0])
    gusts = (effects.turbulence.sample(n * substeps, h, streams[1]) if effects.turbulence is not None
             else np.zeros((n * substeps, E.shape[1])))
    servo = ServoState(effects.servo, h, streams[4])
    x, speed = np.zeros(len(A)), np.zeros(2)
    states, sticks = np.empty((n, len(A))), np.empty((n, len(STICKS)))
    for k in range(n):
        states[k] = x
        sticks[k] = np.clip(extra[k] - K @ x, -1.0, 1.0)
        servo.frame(sticks[k], time[k])
        for j, gust in enumerate(gusts[k * substeps:(k + 1) * substeps]):
            position = servo.step(servo.reaching(time[k] + j * h))
            accel = B @ position + E @ gust
            if effects.drag is not None:
                accel += effects.drag.accel(x, gust)
            if effects.governor is not None:
                accel += effects.governor.accel(speed[0], position, B)
                speed = effects.governor.advance(speed, position[_COL], h)
            x = Ad @ x + G @ accel
        if not np.all(np.isfinite(x)):
            raise ValueError("truth flight: the pilot lost control (non-finite states)")
    reading = read(states, outputs, effects.imu)
    if effects.bias is not None:
        reading[:, outputs.index(effects.bias.channel)] += effects.bias.sample(time, streams[2])
    if effects.vibration is not None:
        for name in effects.vibration.channels:
            reading[:, outputs.index(name)] += effects.vibration.sample(time)
    measured = reading + streams[3].standard_normal(reading.shape) * np.asarray(noise)[None, :]
    if effects.quantiser is not None:
        reading, measured = (effects.quantiser.apply(y, outputs) for y in (reading, measured))
    return Record(time, sticks, states, reading, measured)
