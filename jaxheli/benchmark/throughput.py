"""Candidate evaluations per second of the population cost, seconds per IWO generation, and the FLOP limit."""

from __future__ import annotations

import time
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from ..data.flight import FlightData
from ..model import LOWER, N_INPUTS, N_STATES, TABLE2, UPPER
from ..optim.iwo import IWO
from ..optim.run import minimize
from ..sim.population import PopulationCost, simulator_cost
from ..sim.simulate import Simulator, simulate

CHANNELS = ("p", "q", "phi", "theta")


def bench_flight(n_samples: int, dt: float = 0.01, seed: int = 0) -> FlightData:
    """A flight of ``n_samples``: multi-sine sticks, Table 2 responses plus 0.01 noise on p, q, phi, theta."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_samples) * dt
    freqs = np.array([0.15, 0.4, 0.9, 1.7, 3.1])
    u = sum(0.04 * np.sin(2 * np.pi * f * t[:, None] + rng.uniform(0, 6, N_INPUTS)) for f in freqs)
    clean = np.asarray(simulate(TABLE2, FlightData(t, u, np.zeros((n_samples, 4)), CHANNELS)))
    return FlightData(t, u, clean + 0.01 * rng.normal(size=clean.shape), CHANNELS, source=f"bench-{n_samples}")


def candidates(count: int, dtype: jnp.dtype, seed: int = 1) -> jax.Array:
    """``count`` candidates drawn uniformly inside the search box."""
    rng = np.random.default_rng(seed)
    return jnp.asarray(LOWER + (UPPER - LOWER) * rng.uniform(size=(count, LOWER.size)), dtype)


def best_seconds(fn: Callable[[], object], repeats: int) -> float:
    """Fastest of ``repeats`` timed calls after one warm-up (compilation); load only ever slows a call."""
    jax.block_until_ready(fn())
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - t0)
    return best


def evaluation_rate(
    sim: Simulator, thetas: jax.Array, target: jax.Array, repeats: int, shard: bool | None = None
) -> float:
    """Candidate evaluations per second of one population-cost call on ``thetas[P, 40]``."""
    return thetas.shape[0] / best_seconds(lambda: simulator_cost(sim, thetas, target, shard=shard), repeats)


def generation_seconds(sim: Simulator, target: jax.Array, generations: int, repeats: int = 2) -> float:
    """Seconds per generation of the paper's IWO (20 -> 40 plants, 2 to 7 seeds each in a 280-slot buffer; only
    the real seeds are scored, ``IWO.score_batch`` at a time)."""
    cost = PopulationCost(sim, target, target.dtype.name)
    opt = IWO(LOWER, UPPER)
    run = lambda: minimize(opt, cost, jax.random.key(0), iterations=generations, chunk=generations,  # noqa: E731
                           progress=False).best_cost
    return best_seconds(run, repeats) / generations


def flops_per_candidate(n_samples: int, channels: int = len(CHANNELS)) -> float:
    """Floating-point operations of one direct simulation and score: ``x+ = Ad x + Bd u`` per sample, the
    outputs' Pearson sums, and the discretisation (a degree-16 Taylor expm of the 17 x 17 augmented matrix
    with about 8 products)."""
    n, m = N_STATES, N_INPUTS
    step = 2 * n * n + 2 * n * m
    score = 6 * channels
    expm = 8 * 2 * (n + m) ** 3
    return n_samples * (step + score) + expm


def matmul_peak(dtype: jnp.dtype, size: int = 2048, repeats: int = 3) -> float:
    """Measured FLOP/s of one large matrix product on the default device (the machine's practical peak)."""
    a = jnp.asarray(np.random.default_rng(0).normal(size=(size, size)), dtype)
    product = jax.jit(lambda x: x @ x)
    return 2.0 * size**3 / best_seconds(lambda: product(a), repeats)
