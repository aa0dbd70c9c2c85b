"""This simulator's own pilot: a hover-holding LQR on the frame clock, plus stick excitation of three styles.

The pilot updates the sticks once per logger frame (a digital radio frame), from the true state of the aircraft
(a pilot sees the helicopter, not its sensors); the logger records those sticks. Weights by Bryson's rule on the
rigid-body states only (u, v 1.5 m/s, w 1 m/s, p, q 2 rad/s, r 1 rad/s, attitudes 0.3 rad, stick 0.1): a calm pilot
(closed-loop time constants near 1 s) whose loop on Table 2 and the R-50 stays stable with 6 frames (0.3 s at 20 Hz)
of link delay on every axis.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.signal

from ._hover import STATES

_LIMITS = {"u": 1.5, "v": 1.5, "w": 1.0, "p": 2.0, "q": 2.0, "r": 1.0, "phi": 0.3, "theta": 0.3}
_STICK = 0.1


def lqr_gain(A: np.ndarray, B: np.ndarray, dt: float) -> np.ndarray:
    """``K`` (4x13) of the discrete LQR at frame time ``dt`` (s) on ``(A, B)`` held over a frame (sticks
    ``-K x``); raises ``ValueError`` if the loop it closes is unstable."""
    Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, np.eye(len(A)), np.zeros_like(B)), dt, method="zoh")
    Q = np.diag([1.0 / _LIMITS[s] ** 2 if s in _LIMITS else 1e-6 for s in STATES])
    R = np.eye(B.shape[1]) / _STICK**2
    P = scipy.linalg.solve_discrete_are(Ad, Bd, Q, R)
    K = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
    if np.max(np.abs(np.linalg.eigvals(Ad - Bd @ K))) >= 1.0:
        raise ValueError("truth pilot: the LQR loop is unstable")
    return K


def excitation(style: str, time: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Sticks ``[N, 4]`` added to the pilot's feedback at frame times ``time`` (s), axis by axis (lat, lon, ped,
    col) in equal windows: ``"doublets"`` (a 3-2-1-1 of 0.15 stick, unit 0.3 s, random sign), ``"validate"`` (the
    held-out flight's 3-2-1-1: 0.18 stick, unit 0.4 s), ``"sweep"`` (a logarithmic sweep of 0.12 stick over
    0.3-3 Hz with raised-cosine ends) or ``"regulation"`` (faint band-limited noise, 0.03 stick rms on every axis)."""
    n, span = len(time), time[-1] - time[0]
    out = np.zeros((n, 4))
    if style == "regulation":
        b, a = scipy.signal.butter(2, 1.5, fs=1.0 / (time[1] - time[0]))
        noise = scipy.signal.lfilter(b, a, rng.standard_normal((n, 4)), axis=0)
        return 0.03 * noise / noise.std(axis=0)
    window = span / 4.0
    for axis in range(4):
        t = time - time[0] - axis * window - 0.5
        if style in ("doublets", "validate"):
            amplitude, unit = (0.15, 0.3) if style == "doublets" else (0.18, 0.4)
            sign = rng.choice([-1.0, 1.0])
            edges = np.cumsum([0.0, 3.0, 2.0, 1.0, 1.0]) * unit
            for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
                out[(t >= lo) & (t < hi), axis] = sign * amplitude * (-1.0) ** k
        elif style == "sweep":
            length = window - 1.0
            inside = (t >= 0) & (t < length)
            f0, f1 = 0.3, 3.0
            phase = 2 * np.pi * f0 * length / np.log(f1 / f0) * (np.exp(t[inside] / length * np.log(f1 / f0)) - 1)
            taper = np.minimum(1.0, np.minimum(t[inside], length - t[inside]) / 1.0)
            out[inside, axis] = 0.12 * np.sin(phase) * (0.5 - 0.5 * np.cos(np.pi * taper))
        else:
            raise ValueError(f"truth pilot: unknown style {style!r}")
    return out
