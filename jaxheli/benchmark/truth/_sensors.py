"""What the logger reads: the states through a misaligned, mis-scaled IMU and a rotated velocity frame, plus a
bias random walk, a vibration line sampled without an anti-alias filter, white noise and quantisation.

The catalogue rotates the ``(u, v)``, ``(p, q)`` and ``(phi, theta)`` pairs by one yaw angle and adds a bias with a
linear drift; here the gyro triad is rotated in three axes (its tilt mixes ``r`` into ``p`` and ``q``), the velocity
frame has its own heading error, the attitude estimator is aligned, and the bias wanders.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._hover import state_index

_GYROS = ("p", "q", "r")


def _rotation(axis: int, angle: float) -> np.ndarray:
    """Right-handed rotation by ``angle`` (rad) about body axis ``axis`` (0 x, 1 y, 2 z)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


@dataclasses.dataclass(frozen=True)
class Imu:
    """The gyro triad mounted at ``yaw`` (rad) and tilted by ``tilt`` (roll, pitch; rad), with scale-factor errors
    ``scale`` on ``p q r`` (fractions); GPS velocity resolved in a frame ``velocity_yaw`` (rad) off the body's."""

    yaw: float = 0.0
    tilt: tuple[float, float] = (0.0, 0.0)
    scale: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity_yaw: float = 0.0

    def gyro_matrix(self) -> np.ndarray:
        """``G`` (3x3): measured ``(p, q, r) = G (p, q, r)`` true, ``G = diag(1 + scale) R^T``, ``R`` the mount."""
        mount = _rotation(2, self.yaw) @ _rotation(1, self.tilt[1]) @ _rotation(0, self.tilt[0])
        return np.diag(1.0 + np.asarray(self.scale)) @ mount.T

    def velocity_matrix(self) -> np.ndarray:
        """``V`` (2x2): measured ``(u, v) = V (u, v)`` true."""
        return _rotation(2, self.velocity_yaw)[:2, :2].T


def read(states: np.ndarray, outputs: tuple[str, ...], imu: Imu | None) -> np.ndarray:
    """Noise-free readings ``[N, k]`` of ``outputs`` from ``states`` ``[N, 13]`` through ``imu`` (ideal if
    ``None``)."""
    columns = {name: states[:, state_index(name)] for name in outputs}
    if imu is not None:
        gyros = imu.gyro_matrix() @ np.stack([states[:, state_index(g)] for g in _GYROS])
        velocity = imu.velocity_matrix() @ states[:, [state_index("u"), state_index("v")]].T
        measured = dict(zip(_GYROS, gyros)) | dict(zip(("u", "v"), velocity))
        columns |= {name: measured[name] for name in outputs if name in measured}
    return np.stack([columns[name] for name in outputs], axis=1)


@dataclasses.dataclass(frozen=True)
class BiasWalk:
    """A sensor bias on ``channel`` starting at ``start`` (the channel's unit) and wandering as a random walk of
    intensity ``intensity`` (unit^2/s): its variance grows as ``intensity t``."""

    channel: str
    start: float
    intensity: float

    def sample(self, time: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The bias at the sample times ``time`` (s, from 0)."""
        steps = rng.standard_normal(len(time) - 1) * np.sqrt(self.intensity * np.diff(time))
        return self.start + np.concatenate([[0.0], np.cumsum(steps)])


@dataclasses.dataclass(frozen=True)
class Vibration:
    """A rotor-harmonic line of ``amplitude`` (channel units) at ``frequency`` (Hz) and ``phase`` (rad) on the
    ``channels`` (the gyros' vibration pick-up), read at the logger's samples with no anti-alias filter."""

    amplitude: float
    frequency: float
    phase: float
    channels: tuple[str, ...] = ("p", "q")

    def sample(self, time: np.ndarray) -> np.ndarray:
        """The line at the sample times ``time`` (s)."""
        return self.amplitude * np.sin(2.0 * np.pi * self.frequency * time + self.phase)

    def alias(self, dt: float) -> float:
        """Where a logger of sample time ``dt`` (s) sees the line (Hz, ``0 .. 1 / (2 dt)``)."""
        rate = 1.0 / dt
        return abs(self.frequency - rate * np.round(self.frequency / rate))


@dataclasses.dataclass(frozen=True)
class Quantiser:
    """An ADC of resolution ``step`` per channel (``{channel: step}``, channel units)."""

    step: dict[str, float]

    def apply(self, y: np.ndarray, outputs: tuple[str, ...]) -> np.ndarray:
        """``y`` ``[N, k]`` rounded to the nearest multiple of each named channel's step."""
        out = np.array(y, dtype=np.float64)
        for name, step in self.step.items():
            k = outputs.index(name)
            out[:, k] = step * np.round(out[:, k] / step)
        return out
