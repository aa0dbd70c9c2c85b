"""Signal preparation the consistency detectors share: low-pass, record edges, ratios of fitted coefficients."""

from __future__ import annotations

import numpy as np
import scipy.signal

from ...data.flight import FlightData
from .._regress import RegressionFit

VELOCITY_CUTOFF_HZ = 2.0
"""Low-pass before the velocity regression (GPS velocities are smooth; the flapping model is quasi-steady)."""

EDGE_S = 0.5
"""Seconds dropped at each end of a regression (filter transients, shifted samples, resampling ringing)."""

MAX_LAG_S = 0.4
"""Largest kinematic lag searched, s."""

MIN_DURATION_S = 2.0
"""Shortest record (after the edges) a check runs on, s."""


def lowpass(x: np.ndarray, cutoff: float, fs: float) -> np.ndarray:
    """Zero-phase order-4 Butterworth low-pass along time (columns of ``x``)."""
    sos = scipy.signal.butter(4, cutoff, fs=fs, output="sos")
    return scipy.signal.sosfiltfilt(sos, x, axis=0)


def signals(flight: FlightData, cutoff: float) -> dict[str, np.ndarray]:
    """Outputs low-passed at ``cutoff`` Hz by name, the roll angle unwrapped first (an inverted vehicle's
    roll jumps between +-pi; the Euler relations use only its sine and cosine)."""
    y = flight.outputs.copy()
    if "phi" in flight.output_names:
        c = flight.output_names.index("phi")
        y[:, c] = np.unwrap(y[:, c])
    y = lowpass(y, cutoff, 1.0 / flight.dt)
    return {n: y[:, i] for i, n in enumerate(flight.output_names)}


def interior(t: np.ndarray, edge: float) -> np.ndarray:
    """Mask of samples more than ``edge`` s from both ends."""
    return (t > t[0] + edge) & (t < t[-1] - edge)


def ratio(fit: RegressionFit, i: int, sign: float, j: int = 0) -> tuple[float, float]:
    """``sign beta_i / beta_j`` and its delta-method 1-sigma."""
    bi, bj = fit.beta[i], fit.beta[j]
    grad = np.zeros_like(fit.beta)
    grad[i], grad[j] = 1.0 / bj, -bi / bj**2
    return float(sign * bi / bj), float(np.sqrt(grad @ fit.cov @ grad))
