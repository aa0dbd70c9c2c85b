"""What the logger reads: the states through a misaligned, mis-scaled IMU and velocity sensor, plus a drifting
bias, a vibration line sampled without an anti-alias filter, white noise and quantisation.

The catalogue rotates the ``(u, v)``, ``(p, q)`` and ``(phi, theta)`` pairs by one yaw angle, scales ``p`` and ``q``,
and adds a bias with a linear drift and a random walk; here the gyro triad is rotated in three axes (its tilt mixes
``r`` into ``p`` and ``q``), the velocity sensor has a mount of its own, tilted (mixing ``w`` into ``u`` and ``v``)
and mis-scaled, the attitude estimator is aligned, and the bias settles as the sensor warms and wanders as a
first-order Gauss-Markov process, whose spectrum is flat below its corner where a walk's grows as ``1/f^2``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.signal

from ._hover import state_index

_GYROS = ("p", "q", "r")
_VELOCITY = ("u", "v", "w")


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
    ``scale`` on ``p q r`` (fractions); the velocity sensor mounted at ``velocity_yaw`` (rad), tilted by
    ``velocity_tilt`` (roll, pitch; rad), with scale-factor errors ``velocity_scale`` on ``u v`` (fractions)."""

    yaw: float = 0.0
    tilt: tuple[float, float] = (0.0, 0.0)
    scale: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity_yaw: float = 0.0
    velocity_tilt: tuple[float, float] = (0.0, 0.0)
    velocity_scale: tuple[float, float] = (0.0, 0.0)

    def gyro_matrix(self) -> np.ndarray:
        """``G`` (3x3): measured ``(p, q, r) = G (p, q, r)`` true, ``G = diag(1 + scale) R^T``, ``R`` the mount."""
        return np.diag(1.0 + np.asarray(self.scale)) @ _mount(self.yaw, self.tilt).T

    def velocity_matrix(self) -> np.ndarray:
        """``V`` (2x3): measured ``(u, v) = V (u, v, w)`` true, the first two rows of ``diag(1 + scale) R^T``."""
        return np.diag(1.0 + np.asarray(self.velocity_scale)) @ _mount(self.velocity_yaw, self.velocity_tilt).T[:2]


def _mount(yaw: float, tilt: tuple[float, float]) -> np.ndarray:
    """A sensor's mount (3x3): yaw (rad) after pitch and roll (``tilt``, rad)."""
    return _rotation(2, yaw) @ _rotation(1, tilt[1]) @ _rotation(0, tilt[0])


def read(states: np.ndarray, outputs: tuple[str, ...], imu: Imu | None) -> np.ndarray:
    """Noise-free readings ``[N, k]`` of ``outputs`` from ``states`` ``[N, 13]`` through ``imu`` (ideal if
    ``None``)."""
    columns = {name: states[:, state_index(name)] for name in outputs}
    if imu is not None:
        gyros = imu.gyro_matrix() @ np.stack([states[:, state_index(g)] for g in _GYROS])
        velocity = imu.velocity_matrix() @ states[:, [state_index(c) for c in _VELOCITY]].T
        measured = dict(zip(_GYROS, gyros)) | dict(zip(("u", "v"), velocity))
        columns |= {name: measured[name] for name in outputs if name in measured}
    return np.stack([columns[name] for name in outputs], axis=1)


@dataclasses.dataclass(frozen=True)
class BiasDrift:
    """A sensor bias on ``channel`` (the channel's unit): ``start`` at switch-on, settling by ``settle`` more with
    time constant ``settle_tau`` (s) as the sensor warms, plus a first-order Gauss-Markov wander of std ``sigma``
    and correlation time ``tau`` (s), stationary from the first sample."""

    channel: str
    start: float
    settle: float
    settle_tau: float
    sigma: float
    tau: float

    def sample(self, time: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The bias at the evenly spaced sample times ``time`` (s, from 0)."""
        a = np.exp(-(time[1] - time[0]) / self.tau)
        shocks = rng.standard_normal(len(time)) * self.sigma
        wander, _ = scipy.signal.lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], shocks[1:], zi=[a * shocks[0]])
        settling = self.settle * (1.0 - np.exp(-time / self.settle_tau))
        return self.start + settling + np.concatenate([shocks[:1], wander])


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
