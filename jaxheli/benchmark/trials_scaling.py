"""Independent IWO trials on one process against several local ``jax.distributed`` processes
(``jaxheli trials-scaling``): cold and warm seconds per process count and the speed-up."""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..distributed import initialize, launch_local, minimize_trials_distributed
from ..model import LOWER, UPPER
from ..optim.iwo import IWO
from ..sim.population import PopulationCost
from ..sim.simulate import make_simulator
from .throughput import bench_flight

_RESULT_TAG = "jaxheli-trials-scaling:"


def trials_scaling(
    *,
    trials: int = 10,
    iterations: int = 50,
    samples: int = 1000,
    dtype: str = "float32",
    processes: Sequence[int] = (1, 2),
    timeout: float = 600.0,
) -> dict:
    """Time ``trials`` IWO trials of ``iterations`` generations on one process and on several local ones.

    The cost is the paper's on a synthetic ``samples``-long flight (:func:`jaxheli.benchmark.throughput.bench_flight`).
    Each setting runs as its own group of processes (:func:`launch_local`, one CPU device each) and times,
    on process 0, a first run (compilation included) and a second, warm one. Returns the settings, one row
    per process count (``cold_s``, ``warm_s``, ``speedup`` = one process's warm seconds over this one's)
    and the largest difference of the best costs from the one-process run.
    """
    argv = [sys.executable, "-c", "from jaxheli.benchmark.trials_scaling import _scaling_worker; "
            f"_scaling_worker({trials:d}, {iterations:d}, {samples:d}, {dtype!r})"]
    rows = []
    for n in processes:
        stdout = launch_local(argv, n, timeout=timeout)[0]
        line = next(s for s in stdout.splitlines() if s.startswith(_RESULT_TAG))
        rows.append({"processes": n, **json.loads(line[len(_RESULT_TAG):])})
    base = rows[0]
    for row in rows:
        row["speedup"] = base["warm_s"] / row["warm_s"]
        row["max_cost_difference"] = float(np.max(np.abs(np.subtract(row["best_cost"], base["best_cost"]))))
    return {"trials": trials, "iterations": iterations, "samples": samples, "dtype": dtype,
            "cores": os.cpu_count(), "rows": rows}


def _scaling_worker(trials: int, iterations: int, samples: int, dtype: str) -> None:
    """One process of :func:`trials_scaling`: join the group, run the trials twice, print timings on process 0."""
    initialize()
    jax.config.update("jax_enable_x64", True)
    flight = bench_flight(samples)
    sim = make_simulator(flight)
    target = jnp.asarray(flight.outputs, dtype)
    cost = PopulationCost(sim, target, dtype)
    opt = IWO(LOWER, UPPER, iterations=iterations)
    keys = jax.random.split(jax.random.key(0), trials)
    seconds = []
    for _ in range(2):
        t0 = time.perf_counter()
        result = minimize_trials_distributed(opt, cost, keys, chunk=iterations, progress=False)
        best = np.asarray(jax.block_until_ready(result.best_cost))
        seconds.append(time.perf_counter() - t0)
    if jax.process_index() == 0:
        print(_RESULT_TAG + json.dumps({"cold_s": seconds[0], "warm_s": seconds[1], "best_cost": best.tolist()}),
              flush=True)
    if jax.distributed.is_initialized():
        jax.distributed.shutdown()


