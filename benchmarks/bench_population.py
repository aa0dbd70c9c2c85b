"""Candidate evaluations per second of the population cost, next to a per-candidate NumPy/SciPy loop.

Both run in the same process on the same 8590-sample flight (the length of the paper's flight A); the
table reports each JAX rate as a ratio to the NumPy loop. Usage::

    python benchmarks/bench_population.py [--sizes 40 400 4000] [--samples 8590] [--x64] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import jax
import numpy as np
import scipy.linalg
import scipy.signal

from jaxheli.flight import FlightData
from jaxheli.model import LOWER, TABLE2, UPPER, build_ab
from jaxheli.population import population_cost
from jaxheli.simulate import simulate

CHANNELS = ("p", "q", "phi", "theta")


def _flight(n: int) -> FlightData:
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.01
    freqs = np.array([0.15, 0.4, 0.9, 1.7, 3.1])
    u = sum(0.04 * np.sin(2 * np.pi * f * t[:, None] + rng.uniform(0, 6, 4)) for f in freqs)
    clean = np.asarray(simulate(TABLE2, FlightData(t, u, np.zeros((n, 4)), CHANNELS)))
    return FlightData(t, u, clean + 0.01 * rng.normal(size=clean.shape), CHANNELS, source="bench")


def _numpy_cost(theta: np.ndarray, flight: FlightData) -> float:
    """Baseline a user would write: expm discretisation, a Python/NumPy recurrence, numpy Pearson."""
    A, B = (np.asarray(m, dtype=np.float64) for m in build_ab(theta))
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = scipy.linalg.expm(M * flight.dt)
    Ad, Bd = E[:n, :n], E[:n, n:]
    idx = [2, 3, 4, 5]
    x = np.zeros(n)
    ys = np.empty((flight.n_samples, 4))
    drive = flight.inputs @ Bd.T
    with np.errstate(all="ignore"):
        for k in range(flight.n_samples):
            ys[k] = x[idx]
            x = Ad @ x + drive[k]
        cost = 0.0
        for c in range(4):
            rho = np.corrcoef(ys[:, c], flight.outputs[:, c])[0, 1]
            cost += (1 - (rho if np.isfinite(rho) else -1.0)) ** 2
    return cost


def _rate(fn, count: int, repeats: int) -> float:
    fn()  # warm-up (compilation)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return count / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[40, 400, 4000])
    parser.add_argument("--samples", type=int, default=8590)
    parser.add_argument("--baseline-candidates", type=int, default=8)
    parser.add_argument("--x64", action="store_true", help="float64 (default float32)")
    parser.add_argument("--out", default=None, help="write the results as JSON here")
    args = parser.parse_args()
    if args.x64:
        jax.config.update("jax_enable_x64", True)
    flight = _flight(args.samples)
    rng = np.random.default_rng(1)
    base = LOWER + (UPPER - LOWER) * rng.uniform(size=(args.baseline_candidates, 40))
    base_rate = _rate(lambda: [_numpy_cost(th, flight) for th in base], len(base), 2)
    rows = []
    for p in args.sizes:
        thetas = LOWER + (UPPER - LOWER) * rng.uniform(size=(p, 40))
        rate = _rate(lambda: population_cost(thetas, flight, outputs=CHANNELS).block_until_ready(), p, 3)
        rows.append({"P": p, "evals_per_s": rate, "ratio_to_numpy": rate / base_rate})
    result = {
        "machine": f"{platform.machine()} {platform.processor() or ''} cores={os.cpu_count()} jax={jax.__version__} "
        f"backend={jax.default_backend()}",
        "dtype": "float64" if args.x64 else "float32",
        "samples": args.samples,
        "numpy_loop_evals_per_s": base_rate,
        "jax": rows,
    }
    print(f"# population cost, N = {args.samples} samples, {result['dtype']}, {result['machine']}")
    print(f"per-candidate NumPy/SciPy loop: {base_rate:.1f} candidate evaluations/s")
    print("| P | evals/s | x NumPy loop |\n|---|---|---|")
    for r in rows:
        print(f"| {r['P']} | {r['evals_per_s']:.0f} | {r['ratio_to_numpy']:.1f} |")
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(result, fh, indent=2)


if __name__ == "__main__":
    main()
