"""One run of ``jaxheli bench``: every performance measurement of the cost kernels, as a JSON-ready dict."""

from __future__ import annotations

import os
import platform
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..data.flight import FlightData

SCAN_LIMIT = 4.0e7
"""The plain scan materialises ``[P, N, k]`` outputs: larger ``P * N`` are skipped (memory, not speed)."""
COST_CANDIDATES = 40
"""Candidates of the cost comparison (IWO scores 40 per device per call)."""
QUICK = dict(sizes=[16, 64], samples=[300], dtypes=["float32"], generations=2, experiment_iterations=3, trials=2,
             repeats=1, model_iterations=3, pem_steps=3, form_samples=[300], form_sizes=[16])
"""Tiny settings of :func:`measure` (a smoke test, seconds)."""


def measure(
    *,
    sizes: Sequence[int],
    samples: Sequence[int],
    dtypes: Sequence[str],
    repeats: int,
    generations: int,
    experiment_iterations: int,
    trials: int,
    experiment_data: str | None = None,
    model_methods: Sequence[str] = (),
    model_iterations: int = 1000,
    pem_steps: int = 200,
    quick: bool = False,
    settings: dict[str, Any] | None = None,
    forms: Sequence[str] = ("auto",),
    form_samples: Sequence[int] | None = None,
    form_sizes: Sequence[int] | None = None,
    costs: bool = True,
    model_fit_dts: Sequence[str | float] = ("full",),
) -> dict:
    """Every measurement of one run, as a JSON-ready dict (printing a line per rate measured).

    Candidate evaluations per second (best of ``repeats``) for each dtype (``"float32"``, ``"float64"``),
    flight length ``samples`` and population size ``sizes``; seconds per IWO generation, timed over
    ``generations`` (0: skip); the paper's experiment, ``trials`` x ``experiment_iterations`` generations
    (0: skip), on the flight ``experiment_data`` (``FILE[:t0-t1]``; default: flight A from the shared data if
    present, else a synthetic 8590-sample flight; with ``quick`` the shortest synthetic flight of ``samples``); the
    time to a model of each of ``model_methods`` (:func:`~jaxheli.benchmark.time_to_model.time_to_model`,
    ``model_iterations`` generations, ``pem_steps`` PEM steps, each method once per fit step of ``model_fit_dts``:
    ``identify``'s ``fit_dt``) on flight A prepared as the paper comparison does
    (with ``quick``, ``experiment_data``, or without the shared data: the experiment's flight); the rates of the costs
    the engines minimise (``costs``). The experiment and the time to a model run
    once per time form of ``forms`` (``"auto"``, ``"scan"``, ``"parallel"``: :mod:`jaxheli.sim.forms`); the scan
    and the parallel form of each recursion in time are timed side by side over ``form_samples`` and, for the
    population cost, ``form_sizes`` (default: ``samples`` and ``sizes``; an empty list skips them), with the table
    they select (:mod:`jaxheli.benchmark.time_forms`). ``settings`` is recorded as the result's ``settings``
    (default: these arguments).
    """
    import jax
    import jax.numpy as jnp

    from ..sim.simulate import make_simulator
    from .baseline import mealpy_rate, numpy_rate
    from .throughput import bench_flight, candidates, evaluation_rate, flops_per_candidate, generation_seconds
    from .throughput import matmul_peak

    devices = jax.local_device_count()
    result: dict = {
        "machine": f"{platform.machine()} {platform.processor() or ''}, {os.cpu_count()} cores, "
        f"jax {jax.__version__}, backend {jax.default_backend()} ({jax.devices()[0].device_kind}), "
        f"{devices} device(s)",
        "devices": devices,
        "settings": settings if settings is not None else {
            "sizes": sizes, "samples": samples, "dtypes": dtypes, "repeats": repeats, "generations": generations,
            "experiment_iterations": experiment_iterations, "trials": trials, "experiment_data": experiment_data,
            "model_methods": list(model_methods), "model_iterations": model_iterations, "pem_steps": pem_steps,
            "quick": quick, "forms": list(forms), "form_samples": form_samples, "form_sizes": form_sizes,
            "costs": costs, "model_fit_dts": list(model_fit_dts)},
        "matmul_peak_flops": {},
        "rates": [],
        "iwo_generation": [],
        "scaling": [],
    }
    flights = {n: bench_flight(n) for n in samples}
    baselines = {n: numpy_rate(f, max(2, min(20, 60000 // n))) for n, f in flights.items()}
    for dtype_name in dtypes:
        dtype = jnp.dtype(dtype_name)
        peak = matmul_peak(dtype)
        result["matmul_peak_flops"][dtype_name] = peak
        for n, flight in flights.items():
            target = jnp.asarray(flight.outputs, dtype)
            sims = {m: make_simulator(flight, method=m) for m in ("scan", "blocked")}
            for p in sizes:
                thetas = candidates(p, dtype)
                row = {"dtype": dtype_name, "N": n, "P": p, "numpy": baselines[n],
                       "flop_limit": peak / flops_per_candidate(n)}
                for method, sim in sims.items():
                    if method == "scan" and p * n > SCAN_LIMIT:
                        continue
                    row[method] = evaluation_rate(sim, thetas, target, repeats, shard=False)
                if devices > 1 and p >= 400:
                    sharded = evaluation_rate(sims["blocked"], thetas, target, repeats, shard=True)
                    result["scaling"].append({"dtype": dtype_name, "N": n, "P": p, "single": row["blocked"],
                                              "sharded": sharded})
                    row["blocked"] = max(row["blocked"], sharded)
                result["rates"].append(row)
                print(_row_text(row), flush=True)
            if generations > 0:
                for method, sim in sims.items():
                    seconds = generation_seconds(sim, target, generations)
                    result["iwo_generation"].append({"dtype": dtype_name, "N": n, "method": method, "seconds": seconds})
    mid = min(flights, key=lambda n: abs(n - 8590))
    rate = mealpy_rate(flights[mid])
    result["mealpy"] = None if rate is None else {"N": mid, "rate": rate}
    form_samples = samples if form_samples is None else form_samples
    form_sizes = sizes if form_sizes is None else form_sizes
    if form_samples:
        from .time_forms import measure_forms

        result["time_forms"] = measure_forms(form_samples, form_sizes, dtypes, max(repeats, 2))
    if experiment_iterations > 0:
        flight = bench_flight(min(samples)) if quick else _experiment_flight(experiment_data)
        result["experiments"] = [_experiment(flight, trials, experiment_iterations, baselines, form) for form in forms]
        result["experiment"] = result["experiments"][0]
    if costs:
        from .costs import cost_rates

        result["costs"] = {"N": mid, "P": COST_CANDIDATES, "rows": cost_rates(flights[mid], COST_CANDIDATES, repeats)}
    if model_methods:
        result["time_to_model"] = [row for form in forms for row in _time_to_model(
            model_methods, model_iterations, pem_steps, baselines, quick, flights, experiment_data, form,
            model_fit_dts)]
    return result


def _time_to_model(methods: Sequence[str], iterations: int, pem_steps: int, baselines: dict[int, float],
                   quick: bool, flights: dict[int, FlightData], experiment_data: str | None, time_form: str,
                   fit_dts: Sequence[str | float]) -> list[dict]:
    from .baseline import numpy_rate
    from .time_to_model import paper_training_flight, time_to_model

    if quick:
        flight = flights[min(flights)]
    elif experiment_data:
        flight = _experiment_flight(experiment_data)
    else:
        try:
            flight = paper_training_flight()
        except FileNotFoundError:
            flight = _experiment_flight(experiment_data)
    rate = baselines.get(flight.n_samples) or numpy_rate(flight, 4)
    return time_to_model(flight, methods=methods, iterations=iterations, pem_steps=pem_steps, numpy_rate=rate,
                         time_form=time_form, fit_dts=fit_dts)


def _experiment(flight: FlightData, trials: int, iterations: int, baselines: dict[int, float], time_form: str
                ) -> dict:
    import jax
    import jax.numpy as jnp

    from .baseline import numpy_rate
    from .experiment import paper_experiment

    e = paper_experiment(flight, trials=trials, iterations=iterations, dtype=jnp.float32, progress=True,
                         time_form=time_form)
    e["numpy_rate"] = baselines.get(flight.n_samples) or numpy_rate(flight, 4)
    e["devices"] = jax.local_device_count()
    return e


def _experiment_flight(spec: str | None) -> FlightData:
    from ..flights import load_flight
    from ..io import load
    from ..io.paths import data_file
    from .throughput import CHANNELS, bench_flight

    if spec:
        return load_flight(spec).select(CHANNELS)
    try:
        return load(data_file("trex550/Data_graphready.mat")).select(CHANNELS)
    except FileNotFoundError:
        return bench_flight(8590)


def _row_text(row: dict) -> str:
    parts = [f"{m} {row[m]:.0f}/s ({row[m] / row['numpy']:.0f}x NumPy)" for m in ("scan", "blocked") if m in row]
    return f"{row['dtype']} N={row['N']} P={row['P']}: " + ", ".join(parts)
