"""Time to a model: wall seconds from a flight to an identified model, compilation included, per method."""

from __future__ import annotations

import time
from collections.abc import Sequence

from ..data.flight import FlightData
from ..identify import identify
from ..io import load
from ..io.paths import data_file
from ..optim.pem import pem

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
) -> list[dict]:
    """Identify ``flight`` once per method, timed end to end (compilation included): ``"pem"``
    (:func:`jaxheli.pem`, ``pem_steps`` Levenberg-Marquardt steps from the middle of the box) and any
    :func:`jaxheli.identify` method (one trial, ``iterations`` generations for the population engines, the
    default polish, standard errors and scores included: what a user waits for).

    Each row: method, seconds, the model's training fit % and Pearson per channel (``identify``'s methods) or its
    sum of squares and steps (PEM), and the seconds the per-candidate NumPy loop at ``numpy_rate`` (simulations/s)
    would spend and their ratio to the measured time: for the population engines on the candidates the run scored;
    for PEM on a forward-difference Jacobian per step, ``steps x (free parameters + 1)`` simulations (an estimate
    from the measured rate, not a run).
    """
    rows = []
    for method in methods:
        start = time.perf_counter()
        if method == "pem":
            fit = pem(flight, max_steps=pem_steps)
            row = {"method": method, "seconds": time.perf_counter() - start, "steps": fit.n_steps,
                   "rss_start": fit.rss_start, "rss": fit.rss, "result": fit.result}
            if numpy_rate:
                row["numpy_simulations"] = fit.n_steps * (len(fit.free) + 1)
                row["numpy_seconds"] = row["numpy_simulations"] / numpy_rate
                row["numpy_ratio"] = row["numpy_seconds"] / row["seconds"]
        else:
            result = identify(flight, method=method, iterations=iterations, trials=1, seed=seed, progress=False)
            row = {"method": method, "seconds": time.perf_counter() - start,
                   "fit_percent": result.train["fit_percent"], "pearson": result.train["pearson"]}
            if numpy_rate and method.startswith("iwo"):
                row["numpy_seconds"] = result.settings["evaluations"] / numpy_rate
                row["numpy_ratio"] = row["numpy_seconds"] / row["seconds"]
        row["samples"] = flight.n_samples
        rows.append(row)
        print(f"time to model, {method}: {row['seconds']:.1f} s", flush=True)
    return rows
