"""Time to a model: wall seconds from a flight to an identified model, compilation included, per method.

Each method runs in a fresh process of its own (``fresh=True``, the default), as ``jaxheli identify`` runs for a
user: JAX's default devices (one on a CPU), nothing compiled before, no persistent cache. Timed inside the bench's
own process instead, a method would read back the programs the ones before it had compiled, and take much less
time than a user's run."""

from __future__ import annotations

import multiprocessing
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from .._progress import active, note, reporting
from ..data.flight import FlightData
from ..identify import identify
from ..io import load
from ..io.paths import data_file
from ..optim.pem import pem
from ..stages import uses

PAPER_PREPARATION = {"trim_samples": 50, "correct_data": True, "lowpass_hz": 3.0}
"""How ``benchmarks/paper_comparison.py`` prepares flight A for training (:func:`jaxheli.gap.prepare.prepare`)."""


def paper_training_flight() -> FlightData:
    """Flight A (``trex550/Data_graphready.mat``, the shared data) prepared as the paper comparison does."""
    from ..gap.prepare import prepare

    return prepare(load(data_file("trex550/Data_graphready.mat")), **PAPER_PREPARATION)


def time_to_model(
    flight: FlightData,
    *,
    methods: Sequence[str] = ("pem", "iwo+polish"),
    iterations: int = 1000,
    pem_steps: int = 200,
    numpy_rate: float | None = None,
    seed: int = 0,
    fresh: bool = True,
    progress: bool | None = None,
    time_form: str = "auto",
    fit_dts: Sequence[str | float] = ("full",),
) -> list[dict]:
    """Identify ``flight`` once per method, timed end to end (compilation included): ``"pem"``
    (:func:`jaxheli.pem`, ``pem_steps`` Levenberg-Marquardt steps from the middle of the box) and any
    :func:`jaxheli.identify` method (one trial, ``iterations`` generations for the population engines, the
    default polish, standard errors and scores included: what a user waits for). With ``fresh`` each method runs in
    a new process (see the module); else in this one, after whatever it compiled before. ``progress``: the run
    writes its stages' progress lines (:mod:`jaxheli._progress`; ``None``: when this process does, so a fresh
    process reports as the bench that started it). ``time_form`` ``"scan"`` or ``"parallel"`` is set as
    ``JAXHELI_TIME_FORM`` in the fresh process (:mod:`jaxheli.sim.forms`; ``"auto"`` leaves the variable as this
    process has it); with ``fresh=False`` this process's setting holds. ``identify``'s methods run once per step of
    ``fit_dts`` (its ``fit_dt``: ``"full"``, ``"auto"`` or seconds).

    Each row: method, seconds, the JAX devices it ran on, the model's training fit % and Pearson per channel
    (``identify``'s methods) or its sum of squares and steps (PEM), and the seconds the per-candidate NumPy loop at
    ``numpy_rate`` (simulations/s) would spend and their ratio to the measured time: for the population engines on
    the candidates the run scored; for PEM on a forward-difference Jacobian per step, ``steps x (free parameters +
    1)`` simulations (an estimate from the measured rate, not a run).
    """
    progress = active() if progress is None else progress
    rows = []
    for method, fit_dt in [(m, d) for m in methods for d in (("full",) if m == "pem" else fit_dts)]:
        step = "" if fit_dt == "full" else f", fit step {fit_dt}"
        note(f"time to a model: {method}{step}" + (" in a fresh process" if fresh else ""))
        args = (flight, method, iterations, pem_steps, seed, progress, fit_dt)
        if fresh:
            with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=_float64,
                                     initargs=(time_form,)) as pool:
                row = pool.submit(_timed, *args).result()
        else:
            row = _timed(*args)
        simulations = row.pop("simulations")
        if numpy_rate and simulations is not None:
            row["numpy_simulations"] = simulations
            row["numpy_seconds"] = simulations / numpy_rate
            row["numpy_ratio"] = row["numpy_seconds"] / row["seconds"]
        rows.append(row)
        print(f"time to model, {method}{step} (time form {time_form}): {row['seconds']:.1f} s", flush=True)
    return rows


def _float64(time_form: str = "auto") -> None:
    """A fresh process's set-up: float64, as the command line runs, and ``time_form`` (unless ``"auto"``) as
    ``JAXHELI_TIME_FORM``."""
    import os

    from ..sim.forms import ENV

    if time_form != "auto":
        os.environ[ENV] = time_form
    import jax

    jax.config.update("jax_enable_x64", True)


def _timed(flight: FlightData, method: str, iterations: int, pem_steps: int, seed: int, progress: bool,
           fit_dt: str | float = "full") -> dict[str, Any]:
    """One method's row of :func:`time_to_model` in this process's precision, with ``simulations``: the NumPy loop's
    work for the same model (``None`` where not counted); with ``progress``, its stages' lines."""
    with reporting(progress):
        return _row(flight, method, iterations, pem_steps, seed, fit_dt)


def _row(flight: FlightData, method: str, iterations: int, pem_steps: int, seed: int, fit_dt: str | float
         ) -> dict[str, Any]:
    import jax

    from ..sim.forms import forced_form

    start = time.perf_counter()
    if method == "pem":
        fit = pem(flight, max_steps=pem_steps)
        row = {"method": method, "seconds": time.perf_counter() - start, "steps": fit.n_steps,
               "rss_start": fit.rss_start, "rss": fit.rss, "result": fit.result,
               "simulations": fit.n_steps * (len(fit.free) + 1)}
    else:
        search = {"iterations": iterations, "progress": False} if uses(method, "iterations") else {}
        result = identify(flight, method=method, trials=1, seed=seed, fit_dt=fit_dt, **search)
        row = {"method": method, "fit_dt": result.settings["fit_dt"], "seconds": time.perf_counter() - start,
               "fit_percent": result.train["fit_percent"], "pearson": result.train["pearson"],
               "simulations": result.settings["evaluations"] if method.startswith("iwo") else None}
    return {**row, "devices": jax.local_device_count(), "samples": flight.n_samples, "time_form": forced_form()}
