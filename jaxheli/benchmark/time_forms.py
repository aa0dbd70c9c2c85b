"""The plain scan against the parallel form of each recursion in time, timed side by side on this machine: the rows
behind :data:`jaxheli.sim.forms.PARALLEL_FROM`, and the table they select (:func:`selection`).

``"population"`` rows time the population cost (the blocked kernel, its block starts in each form) over flight
length N and population size P; ``"recursion"`` rows time what each step of the output-error polish computes, the
outputs of 5-s runs from estimated initial states and their Jacobian over the 40 parameters (forward mode: 40
tangents), in float64. The two forms are timed alternately (A B, then B A, ...), best of ``repeats`` after a
compiling call, so that a machine's changing load weighs on both alike; each row also gives the largest relative
difference between the forms' results.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..model import N_STATES, TABLE2
from ..sim.forms import MAX_PARALLEL_ELEMENTS, PATHS, backend_key
from ..sim.population import simulator_cost
from ..sim.shooting import estimated_outputs
from ..sim.simulate import make_simulator
from .throughput import bench_flight, candidates

FORMS = ("scan", "parallel")
RUN_S = 5.0
"""Run length (s) of the recursion rows' estimated runs (the polish's first round)."""


def alternate(calls: dict[str, Callable[[], object]], repeats: int) -> dict[str, dict[str, float]]:
    """``{name: {"first_s", "best_s"}}``: each call once to compile (``first_s``, compilation included), then
    ``repeats`` rounds timing every call, the order reversed each round; ``best_s`` the fastest."""
    out = {}
    for name, call in calls.items():
        t0 = time.perf_counter()
        jax.block_until_ready(call())
        out[name] = {"first_s": time.perf_counter() - t0, "best_s": np.inf}
    names = list(calls)
    for r in range(repeats):
        for name in (names if r % 2 == 0 else names[::-1]):
            t0 = time.perf_counter()
            jax.block_until_ready(calls[name]())
            out[name]["best_s"] = min(out[name]["best_s"], time.perf_counter() - t0)
    return out


def _difference(a: object, b: object) -> float:
    """Largest ``|a - b|`` over the finite entries, relative to the largest ``|b|``."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    ok = np.isfinite(a) & np.isfinite(b)
    scale = np.max(np.abs(b[ok])) if ok.any() else 1.0
    return float(np.max(np.abs(a[ok] - b[ok])) / (scale or 1.0)) if ok.any() else 0.0


def _row(row: dict, timed: dict[str, dict[str, float]], values: dict[str, object]) -> dict:
    for form, t in timed.items():
        row[f"{form}_s"], row[f"{form}_first_s"] = t["best_s"], t["first_s"]
    if "parallel" in timed:
        row["parallel_over_scan"] = timed["parallel"]["best_s"] / timed["scan"]["best_s"]
        row["difference"] = _difference(values["parallel"], values["scan"])
    return row


def population_rows(samples: Sequence[int], sizes: Sequence[int], dtype: str, repeats: int,
                    max_elements: int = MAX_PARALLEL_ELEMENTS) -> list[dict]:
    """One row per flight length and population size: seconds of one population-cost call (single device) with the
    block starts scanned and in parallel (``parallel`` skipped, ``"skipped": "memory"``, where its per-step matrices
    would exceed ``max_elements``)."""
    rows = []
    for n in samples:
        flight = bench_flight(n)
        target = jnp.asarray(flight.outputs, dtype)
        sims = {form: make_simulator(flight, method="blocked", time_form=form) for form in FORMS}
        steps = sims["scan"].plan().n_blocks
        for p in sizes:
            thetas = candidates(p, jnp.dtype(dtype))
            row = {"path": "population", "dtype": dtype, "N": n, "P": p, "steps": steps}
            forms = FORMS
            if steps * N_STATES * N_STATES * p > max_elements:
                forms, row["skipped"] = ("scan",), "memory"
            calls = {f: (lambda s=sims[f]: simulator_cost(s, thetas, target, shard=False)) for f in forms}
            rows.append(_row(row, alternate(calls, repeats), {f: calls[f]() for f in forms}))
            print(_text(rows[-1]), flush=True)
    return rows


@eqx.filter_jit
def _outputs_and_jacobian(sim, theta):
    """The estimated runs' outputs and their Jacobian over ``theta`` (one forward-mode pass)."""
    jacobian, outputs = jax.jacfwd(lambda t: (estimated_outputs(sim, t),) * 2, has_aux=True)(theta)
    return outputs, jacobian


def recursion_rows(samples: Sequence[int], repeats: int) -> list[dict]:
    """One row per flight length: seconds of the polish's outputs and Jacobian (40 tangents, float64, runs of
    :data:`RUN_S`) with the recursions scanned and in parallel."""
    rows = []
    theta = jnp.asarray(TABLE2, jnp.float64)
    for n in samples:
        flight = bench_flight(n)
        sims = {form: make_simulator(flight, x0="estimated", segment=RUN_S, time_form=form) for form in FORMS}
        calls = {f: (lambda s=sims[f]: _outputs_and_jacobian(s, theta)) for f in FORMS}
        row = {"path": "recursion", "dtype": "float64", "N": n, "tangents": theta.size, "steps": n - 1}
        rows.append(_row(row, alternate(calls, repeats), {f: calls[f]()[1] for f in FORMS}))
        print(_text(rows[-1]), flush=True)
    return rows


def selection(rows: Sequence[dict], backend: str | None = None) -> dict[str, dict[str, int | None]]:
    """The table :func:`jaxheli.sim.forms.choose_form` reads, from ``rows`` measured on ``backend`` (default: JAX's):
    per path, the fewest steps measured at which the parallel form was faster in every row there and at every longer
    recursion measured (``None``: it never was, or the path was not measured)."""
    backend = backend_key(backend or jax.default_backend())
    table: dict[str, int | None] = {}
    for path in PATHS:
        wins: dict[int, bool] = {}
        for r in rows:
            if r["path"] == path and "parallel_s" in r:
                wins[r["steps"]] = wins.get(r["steps"], True) and r["parallel_s"] < r["scan_s"]
        threshold = None
        for steps in sorted(wins, reverse=True):
            if not wins[steps]:
                break
            threshold = steps
        table[path] = threshold
    return {backend: table}


def measure_forms(samples: Sequence[int], sizes: Sequence[int], dtypes: Sequence[str], repeats: int) -> dict:
    """Both paths' rows (population in each of ``dtypes``), the backend they ran on and their :func:`selection`."""
    rows = [r for dtype in dtypes for r in population_rows(samples, sizes, dtype, repeats)]
    rows += recursion_rows(samples, repeats)
    backend = jax.default_backend()
    return {"backend": backend, "device": jax.devices()[0].device_kind,
            "matmul_precision": str(jax.config.jax_default_matmul_precision), "rows": rows,
            "selection": selection(rows, backend)}


def _text(row: dict) -> str:
    size = f"P={row['P']}" if row["path"] == "population" else f"{row['tangents']} tangents"
    text = (f"time forms, {row['path']} {row['dtype']} N={row['N']} {size} ({row['steps']} steps): "
            f"scan {row['scan_s']:.4g} s")
    if "parallel_s" in row:
        text += (f", parallel {row['parallel_s']:.4g} s ({row['parallel_over_scan']:.2f}x the scan's time, "
                 f"difference {row['difference']:.1e})")
    return text + (f", parallel skipped ({row['skipped']})" if "skipped" in row else "")
