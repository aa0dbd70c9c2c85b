"""What a user without jaxheli would run: a per-candidate NumPy/SciPy loop, and mealpy's IWO driving it."""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg

from ..data.flight import FlightData
from ..model import LOWER, UPPER, build_ab, output_indices


def numpy_cost(theta: np.ndarray, flight: FlightData) -> float:
    """The paper's cost of one candidate: ``expm`` discretisation, a Python/NumPy recurrence, NumPy Pearson.

    Zero-order hold from rest on every output channel of ``flight``; a non-finite channel scores worst.
    """
    A, B = (np.asarray(m, dtype=np.float64) for m in build_ab(np.asarray(theta, np.float64)))
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = scipy.linalg.expm(M * flight.dt)
    Ad, Bd = E[:n, :n], E[:n, n:]
    idx = output_indices(flight.output_names)
    x = np.zeros(n)
    ys = np.empty((flight.n_samples, len(idx)))
    drive = flight.inputs @ Bd.T
    cost = 0.0
    with np.errstate(all="ignore"):
        for k in range(flight.n_samples):
            ys[k] = x[idx]
            x = Ad @ x + drive[k]
        for c in range(len(idx)):
            rho = np.corrcoef(ys[:, c], flight.outputs[:, c])[0, 1]
            cost += (1.0 - (rho if np.isfinite(rho) else -1.0)) ** 2
    return cost


def numpy_rate(flight: FlightData, candidates: int, seed: int = 1) -> float:
    """Candidate evaluations per second of :func:`numpy_cost` (best of two passes over ``candidates``)."""
    thetas = _draw(candidates, seed)
    best = np.inf
    for _ in range(2):
        t0 = time.perf_counter()
        for theta in thetas:
            numpy_cost(theta, flight)
        best = min(best, time.perf_counter() - t0)
    return candidates / best


def mealpy_rate(flight: FlightData, epochs: int = 2, pop_size: int = 10, seed: int = 1) -> float | None:
    """Evaluations per second of mealpy's ``OriginalIWO`` on :func:`numpy_cost` (``None`` without mealpy).

    mealpy scores one candidate per call, so it cannot batch; install it with
    ``pip install --no-deps -r benchmarks/requirements-mealpy.txt`` (its metadata pins NumPy 1.x, but it
    runs on the NumPy this project pins).
    """
    try:
        from mealpy import IWO, FloatVar
    except ImportError:
        return None
    calls = [0]

    def objective(theta: np.ndarray) -> float:
        calls[0] += 1
        return numpy_cost(theta, flight)

    free = UPPER > LOWER
    problem = {
        "obj_func": lambda v: objective(_fill(v, free)),
        "bounds": FloatVar(lb=LOWER[free].tolist(), ub=UPPER[free].tolist()),
        "minmax": "min",
        "log_to": None,
    }
    model = IWO.OriginalIWO(epoch=epochs, pop_size=pop_size, seed_min=2, seed_max=5)
    t0 = time.perf_counter()
    model.solve(problem, seed=seed)
    return calls[0] / (time.perf_counter() - t0)


def _fill(values: np.ndarray, free: np.ndarray) -> np.ndarray:
    theta = LOWER.copy()
    theta[free] = values
    return theta


def _draw(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return LOWER + (UPPER - LOWER) * rng.uniform(size=(count, LOWER.size))
