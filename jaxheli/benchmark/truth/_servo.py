"""The path from a logged stick to the rotor: a radio link with latency, jitter and lost frames, then a servo with
hard travel stops, a rate limit, second-order dynamics and backlash in its linkage, per axis.

The catalogue's forms are a fractional, interpolated delay, a smooth ``u / sqrt(1 + k u^2)`` saturation and a
first-order lag; these are the hardware's own: frames that arrive late or not at all, hard stops and rate limits, an
exactly discretised second-order servo at a finer step, a linkage that holds inside its play.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

_AXES = 4
_EPS = 1e-9
"""Time tolerance (s) when a frame's arrival is compared with a servo step's start."""


@dataclasses.dataclass(frozen=True)
class Servo:
    """Per-axis servo chain (``lat lon ped col``). The link: each logged frame reaches axis ``i`` ``delay[i]`` s
    after it is logged plus a jitter, the absolute value of a normal draw of std ``jitter`` (s, one per frame), and
    is lost with probability ``drop``; frames arrive in order (a late frame holds back the next), and a servo holds
    the last frame that reached it. The servo: travel ``limit`` (stick), rate ``rate`` (stick/s), natural frequency
    ``wn`` (rad/s) and damping ``zeta``, and a linkage ``backlash`` (stick, the width of the play). ``inf`` limits,
    rates and ``wn``, and zero delay, jitter, drop and backlash, are an ideal chain."""

    delay: tuple[float, ...] = (0.0,) * _AXES
    jitter: float = 0.0
    drop: float = 0.0
    limit: tuple[float, ...] = (np.inf,) * _AXES
    rate: tuple[float, ...] = (np.inf,) * _AXES
    wn: tuple[float, ...] = (np.inf,) * _AXES
    zeta: tuple[float, ...] = (0.7,) * _AXES
    backlash: tuple[float, ...] = (0.0,) * _AXES


class ServoState:
    """A servo chain in motion at internal step ``h`` (s): the frames in flight on the link (``rng`` draws their
    jitter and losses), and position, rate and linkage output per axis."""

    def __init__(self, servo: Servo, h: float, rng: np.random.Generator | None = None) -> None:
        self.h = h
        self.rng = np.random.default_rng(0) if rng is None else rng
        self.delay = np.asarray(servo.delay, dtype=np.float64)
        self.jitter, self.drop = float(servo.jitter), float(servo.drop)
        self.arrivals: list[np.ndarray] = []
        self.commands: list[np.ndarray] = []
        self.next = np.zeros(_AXES, dtype=int)
        self.held = np.zeros(_AXES)
        self.limit = np.asarray(servo.limit, dtype=np.float64)
        self.rate = np.asarray(servo.rate, dtype=np.float64)
        self.backlash = np.asarray(servo.backlash, dtype=np.float64)
        self.position = np.zeros(_AXES)
        self.speed = np.zeros(_AXES)
        self.linkage = np.zeros(_AXES)
        self.dynamic = np.isfinite(servo.wn)
        self.step_matrix = [_second_order(w, z, h) if d else None
                            for w, z, d in zip(servo.wn, servo.zeta, self.dynamic)]

    def frame(self, command: np.ndarray, t: float) -> None:
        """Send the frame ``command`` (4 sticks) logged at time ``t`` (s) over the link."""
        late = abs(self.rng.standard_normal()) * self.jitter
        if self.rng.random() < self.drop:
            return
        arrival = t + self.delay + late
        if self.arrivals:
            arrival = np.maximum(arrival, self.arrivals[-1])
        self.arrivals.append(arrival)
        self.commands.append(np.asarray(command, dtype=np.float64).copy())

    def reaching(self, t: float) -> np.ndarray:
        """What has reached each axis's servo by time ``t`` (s): the last frame arrived (zero before the first)."""
        for i in range(_AXES):
            while self.next[i] < len(self.arrivals) and self.arrivals[self.next[i]][i] <= t + _EPS:
                self.held[i] = self.commands[self.next[i]][i]
                self.next[i] += 1
        return self.held.copy()

    def step(self, command: np.ndarray) -> np.ndarray:
        """Advance one internal step toward ``command`` (stick) and return what the linkage passes on."""
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
        half = 0.5 * self.backlash
        self.linkage = np.clip(self.linkage, self.position - half, self.position + half)
        return self.linkage.copy()


def _second_order(wn: float, zeta: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact step ``h`` of ``s'' = wn^2 (c - s) - 2 zeta wn s'`` for ``c`` held: ``(Ad 2x2, bd 2)`` on ``(s, s')``."""
    M = np.array([[0.0, 1.0, 0.0], [-wn**2, -2.0 * zeta * wn, wn**2], [0.0, 0.0, 0.0]])
    E = scipy.linalg.expm(M * h)
    return E[:2, :2], E[:2, 2]
