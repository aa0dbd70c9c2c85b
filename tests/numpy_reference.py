"""Plain numpy/scipy references the tests compare jaxheli's simulations against."""

import numpy as np
import scipy.linalg

from jaxheli.model import build_ab, output_indices
from jaxheli.sim.shooting import RIDGE


def estimated_runs(theta, flight, segment, outputs):
    """``flight``'s ``outputs`` simulated under ``theta`` in runs of ``segment`` s (``None``: one run), each from
    rest by scipy's ZOH plus its start by a weighted (ridged) least-squares fit, in plain numpy; and the starts."""
    A, B = (np.asarray(m) for m in build_ab(theta))
    M = scipy.linalg.expm(np.block([[A, B], [np.zeros((4, 17))]]) * flight.dt)
    Ad, Bd = M[:13, :13], M[:13, 13:]
    u, n, idx = flight.inputs, flight.n_samples, output_indices(outputs)
    meas = flight.select(outputs).outputs
    w = 1.0 / meas.std(axis=0) ** 2
    L = n - 1 if segment is None else int(round(segment / flight.dt))
    out, starts, first, begin = np.zeros_like(meas), [], True, 0
    while first or begin < n - 1:
        end = min(begin + L, n - 1)
        steps = np.arange(begin if first else begin + 1, end + 1)
        forced, power = {begin: np.zeros(13)}, {begin: np.eye(13)}
        for k in range(begin, end):
            forced[k + 1], power[k + 1] = Ad @ forced[k] + Bd @ u[k], Ad @ power[k]
        G = np.concatenate([power[k][idx] * np.sqrt(w)[:, None] for k in steps])
        e = np.concatenate([(meas[k] - forced[k][idx]) * np.sqrt(w) for k in steps])
        gram = G.T @ G
        x0 = np.linalg.solve(gram + RIDGE * np.trace(gram) / 13 * np.eye(13), G.T @ e)
        for k in steps:
            out[k] = forced[k][idx] + power[k][idx] @ x0
        starts.append(x0)
        begin, first = end, False
    return out, np.array(starts)
