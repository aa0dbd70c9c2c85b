"""The path from a logged stick to the rotor: a link latency in whole logger frames, then a servo with hard travel
stops, a rate limit and second-order dynamics, per axis.

The catalogue's forms are a fractional, interpolated delay, a smooth ``u / sqrt(1 + k u^2)`` saturation and a
first-order lag; these are the hardware's own.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

_AXES = 4


@dataclasses.dataclass(frozen=True)
class Servo:
    """Per-axis servo chain (``lat lon ped col``): ``delay`` whole logger frames, travel ``limit`` (stick), rate
    ``rate`` (stick/s), natural frequency ``wn`` (rad/s) and damping ``zeta``; ``inf`` limits, rates and ``wn``
    are an ideal servo."""

    delay: tuple[int, ...] = (0,) * _AXES
    limit: tuple[float, ...] = (np.inf,) * _AXES
    rate: tuple[float, ...] = (np.inf,) * _AXES
    wn: tuple[float, ...] = (np.inf,) * _AXES
    zeta: tuple[float, ...] = (0.7,) * _AXES


class ServoState:
    """A servo chain in motion at internal step ``h`` (s): the pending frames, and position and rate per axis."""

    def __init__(self, servo: Servo, h: float) -> None:
        self.h = h
        self.delay = np.asarray(servo.delay, dtype=int)
        self.pending = np.zeros((int(self.delay.max()) + 1, _AXES))
        self.limit = np.asarray(servo.limit, dtype=np.float64)
        self.rate = np.asarray(servo.rate, dtype=np.float64)
        self.position = np.zeros(_AXES)
        self.speed = np.zeros(_AXES)
        self.dynamic = np.isfinite(servo.wn)
        self.step_matrix = [_second_order(w, z, h) if d else None
                            for w, z, d in zip(servo.wn, servo.zeta, self.dynamic)]

    def frame(self, command: np.ndarray) -> np.ndarray:
        """Log the frame's ``command`` (4 sticks) and return what reaches the servos this frame: each axis's
        command ``delay`` frames old (zero before the flight)."""
        self.pending = np.roll(self.pending, 1, axis=0)
        self.pending[0] = command
        return self.pending[self.delay, np.arange(_AXES)]

    def step(self, command: np.ndarray) -> np.ndarray:
        """Advance one internal step toward ``command`` (stick) and return the servo positions."""
        target = np.clip(command, -self.limit, self.limit)
        old = self.position.copy()
        for i in range(_AXES):
            if self.dynamic[i]:
                Ad, bd = self.step_matrix[i]
                self.position[i], self.speed[i] = Ad @ (self.position[i], self.speed[i]) + bd * target[i]
            else:
                self.position[i] = target[i]
        move = np.clip(self.position - old, -self.rate * self.h, self.rate * self.h)
        self.speed = np.where(move != self.position - old, move / self.h, self.speed)
        self.speed = np.where(np.abs(old + move) > self.limit, 0.0, self.speed)
        self.position = np.clip(old + move, -self.limit, self.limit)
        return self.position.copy()


def _second_order(wn: float, zeta: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact step ``h`` of ``s'' = wn^2 (c - s) - 2 zeta wn s'`` for ``c`` held: ``(Ad 2x2, bd 2)`` on ``(s, s')``."""
    M = np.array([[0.0, 1.0, 0.0], [-wn**2, -2.0 * zeta * wn, wn**2], [0.0, 0.0, 0.0]])
    E = scipy.linalg.expm(M * h)
    return E[:2, :2], E[:2, 2]

