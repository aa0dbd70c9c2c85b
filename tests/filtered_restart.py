"""Independent numpy/scipy reference of the diagnosis predictor on the base model (no effect): a ZOH
simulation restarted every segment from a steady-state Kalman filter's estimate (scipy's DARE), written as
a plain Python loop over samples."""

import numpy as np
import scipy.linalg

from jaxheli.model import STATE_NAMES, build_ab, output_indices

GUST = ("u", "v", "w")


def reference_prediction(theta, flight, segment=2.0, track=0.1, g=9.81, smooth=False):
    """Predicted outputs ``[N, k]`` of ``theta`` on ``flight`` (all its channels); ``smooth``: each segment's
    restart state then moved by the least squares of the segment's readings with the filter's covariance as its
    prior (normal equations, one segment at a time)."""
    A, B = (np.asarray(M) for M in build_ab(np.asarray(theta), g))
    wind = -A[:, [STATE_NAMES.index(s) for s in GUST]]
    n, m, dt = A.shape[0], len(GUST), flight.dt
    big = np.zeros((n + 4 + m, n + 4 + m))
    big[:n, :n], big[:n, n:n + 4], big[:n, n + 4:] = A, B, wind
    E = scipy.linalg.expm(big * dt)
    Ad, Bd, Ed = E[:n, :n], E[:n, n:n + 4], E[:n, n + 4:]
    rho = np.exp(-dt / 1.0)
    idx = output_indices(flight.output_names)
    C = np.eye(n)[idx]
    y, u = flight.outputs, flight.inputs
    var = np.maximum(np.mean(np.diff(y, n=2, axis=0) ** 2, axis=0) / 6.0, 1e-10)
    F = np.block([[Ad, Ed], [np.zeros((m, n)), rho * np.eye(m)]])
    G = np.vstack([Bd, np.zeros((m, 4))])
    H = np.hstack([C, np.zeros((len(idx), m))])
    Q = np.diag(np.r_[track**2 * (C.T @ var), np.zeros(m)] + 1e-12)
    R = np.diag(var)
    P = scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    seg = int(round(segment / dt))
    x = np.zeros(n)
    x[idx] = y[0]
    z, w = np.r_[x, np.zeros(m)], np.zeros(m)
    out = np.empty_like(y)
    out[0] = y[0]
    for k in range(len(y) - 1):
        x = Ad @ x + Bd @ u[k] + Ed @ w
        z = F @ z + G @ u[k]
        z = z + K @ (y[k + 1] - H @ z)
        out[k + 1] = x[idx]
        if (k + 1) % seg == 0:
            x, w = z[:n].copy(), z[n:].copy()
        else:
            w = rho * w
    if smooth:
        updated = P - P @ H.T @ np.linalg.solve(H @ P @ H.T + R, H @ P)
        for start in range(0, len(y) - 1, seg):
            times = range(start + 1, min(start + seg, len(y) - 1) + 1)
            phis = [H @ np.linalg.matrix_power(F, t - start) for t in times]
            info = np.linalg.inv(updated) + sum(p.T @ np.linalg.solve(R, p) for p in phis)
            rhs = sum(p.T @ np.linalg.solve(R, y[t] - out[t]) for p, t in zip(phis, times))
            d = np.linalg.solve(info, rhs)
            for p, t in zip(phis, times):
                out[t] = out[t] + p @ d
    return out
