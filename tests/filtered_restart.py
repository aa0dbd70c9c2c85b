"""Independent numpy/scipy reference of the diagnosis predictor on the base model (no effect): a ZOH
simulation restarted every segment from a steady-state Kalman filter's estimate (scipy's DARE), written as
a plain Python loop over samples."""

import numpy as np
import scipy.linalg

from jaxheli.model import STATE_NAMES, build_ab, output_indices

GUST = ("u", "v", "w")


def reference_prediction(theta, flight, segment=2.0, track=0.1, g=9.81, smooth=False, walk=None, biases=True,
                         revert=0.0):
    """Predicted outputs ``[N, k]`` of ``theta`` on ``flight`` (all its channels); ``smooth``: each segment's
    restart state then moved by the least squares of the segment's readings with the filter's covariance as its
    prior (normal equations, one segment at a time). Each channel's reading carries a random-walk bias of
    intensity ``walk[k]`` (unit per sqrt(s); ``None``: none, a variance floor of 1e-12 times the channel's noise
    variance per sample) reverting at ``revert`` (1/s; 0: a random walk), estimated by the filter, restarted with the
    state and decaying at that rate inside each segment (held at 0), and
    (``smooth``) anchored at zero in the first segment by a prior information of 1e6 times the channel's;
    ``biases=False``: no bias states at all."""
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
    k = len(idx)
    b = k if biases else 0
    walk = np.zeros(k) if walk is None else np.asarray(walk, dtype=float)
    rho_bias = np.exp(-revert * dt)
    F = scipy.linalg.block_diag(np.block([[Ad, Ed], [np.zeros((m, n)), rho * np.eye(m)]]), rho_bias * np.eye(b))
    G = np.vstack([Bd, np.zeros((m + b, 4))])
    H = np.hstack([C, np.zeros((k, m)), np.eye(k)[:, :b]])
    Q = np.diag(np.r_[track**2 * (C.T @ var) + 1e-12, np.full(m, 1e-12), (walk**2 * dt + 1e-12 * var)[:b]])
    R = np.diag(var)
    P = scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    seg = int(round(segment / dt))
    x = np.zeros(n)
    x[idx] = y[0]
    z, w, bias = np.r_[x, np.zeros(m + b)], np.zeros(m), np.zeros(k)
    out = np.empty_like(y)
    out[0] = y[0]
    for i in range(len(y) - 1):
        x = Ad @ x + Bd @ u[i] + Ed @ w
        z = F @ z + G @ u[i]
        z = z + K @ (y[i + 1] - H @ z)
        out[i + 1] = x[idx] + bias
        if (i + 1) % seg == 0:
            x, w = z[:n].copy(), z[n:n + m].copy()
            bias = z[n + m:].copy() if biases else bias
        else:
            w, bias = rho * w, rho_bias * bias
    if smooth:
        updated = P - P @ H.T @ np.linalg.solve(H @ P @ H.T + R, H @ P)
        for start in range(0, len(y) - 1, seg):
            times = range(start + 1, min(start + seg, len(y) - 1) + 1)
            phis = [H @ np.linalg.matrix_power(F, t - start) for t in times]
            info = np.linalg.inv(updated) + sum(p.T @ np.linalg.solve(R, p) for p in phis)
            if start == 0:  # the record's start: the biases are the fixed ones (their walk is zero)
                info = info + np.diag(np.r_[np.zeros(n + m), (1e6 / var)[:b]])
            rhs = sum(p.T @ np.linalg.solve(R, y[t] - out[t]) for p, t in zip(phis, times))
            d = np.linalg.solve(info, rhs)
            for p, t in zip(phis, times):
                out[t] = out[t] + p @ d
    return out
