"""A model against a flight end to end: simulate it, localise its gap (:func:`~jaxheli.gap.localise.localise`),
compare its frequency response with the flight's estimate, and write the report and plots."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..data.flight import FlightData, default_outputs
from ..evaluate import resolve_params, started_simulator
from ..model import G_SI, INPUT_NAMES
from ..problem import make_problem
from ..spectra import FrequencyResponse, estimate_frequency_response, mismatch, model_frequency_response
from .localisation_record import Localisation
from .localise import localise


def frequency_comparison(
    theta: np.ndarray, flight: FlightData, outputs: Sequence[str], g: float = G_SI, **welch
) -> tuple[FrequencyResponse, np.ndarray]:
    """Flight estimate (sticks to measured ``outputs``) and the model's continuous response on its grid."""
    estimate = estimate_frequency_response(flight.inputs, flight.select(outputs).outputs, flight.dt, **welch)
    model = np.asarray(model_frequency_response(theta, estimate.freq, outputs, g))
    return estimate, model


def localise_model(
    params,
    flight: FlightData,
    *,
    outputs: Sequence[str] | None = None,
    x0: str | np.ndarray = "estimate",
    min_coherence: float = 0.6,
    localise_options: dict | None = None,
    **sim_options,
) -> tuple[Localisation, np.ndarray]:
    """Simulate ``params`` (anything :func:`jaxheli.resolve_params` takes) on ``flight`` and localise the gap.

    ``x0`` as in :func:`jaxheli.evaluate`; ``sim_options`` are :class:`~jaxheli.problem.Settings` fields
    (``hold``, ``g``, ``segment``). Returns the
    localisation (:func:`localise`'s, with ``frequency_response``: per ``input->output`` pair the
    coherent bins, mean magnitude (dB) and phase (deg) errors and CIFER cost from :func:`mismatch`, and
    ``simulation``) and the simulated outputs ``[N, k]``.
    """
    theta = resolve_params(params)
    names = tuple(outputs) if outputs is not None else default_outputs(flight)
    sim = started_simulator(make_problem(flight, outputs=names, **sim_options), theta, x0)
    simulated = np.asarray(sim(theta))
    settings = sim.describe()
    settings["initial_state"] = x0 if isinstance(x0, str) else "given"
    report = localise_prediction(theta, flight, simulated, names, settings, min_coherence=min_coherence,
                                 localise_options=localise_options)
    return report, simulated


def localise_prediction(
    theta: np.ndarray,
    flight: FlightData,
    simulated: np.ndarray,
    outputs: Sequence[str],
    simulation: Mapping[str, Any],
    *,
    min_coherence: float = 0.6,
    localise_options: dict | None = None,
) -> Localisation:
    """Localise the gap between ``flight`` and any prediction ``simulated[N, k]`` of ``theta`` on ``outputs``.

    ``simulation`` describes how the prediction was made (JSON settings, kept as the localisation's
    ``simulation``; its ``g``, m/s^2, also sets the model frequency response). Returns :func:`localise`'s
    localisation with ``frequency_response`` (see :func:`localise_model`) and ``simulation``.
    """
    names = tuple(outputs)
    found = localise(flight, simulated, names, **(localise_options or {}))
    estimate, model = frequency_comparison(theta, flight, names, simulation["g"])
    errors = mismatch(estimate, model, min_coherence=min_coherence)
    response = {
        f"{i}->{o}": {key: (None if not np.isfinite(v[k, m]) else float(v[k, m])) for key, v in errors.items()}
        for m, i in enumerate(INPUT_NAMES) for k, o in enumerate(names)
    }
    return dataclasses.replace(found, frequency_response=response, simulation=simulation)


def write_localisation(report: Localisation, theta: np.ndarray, flight: FlightData, out: str | Path) -> list[Path]:
    """Write ``localisation.json`` and the PNG plots (bands, lags, frequency response) into ``out``."""
    from ..plots import plot_frequency_response
    from .plots import plot_lag_correlation, plot_residual_bands

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = tuple(report.channel)
    path = out / "localisation.json"
    path.write_text(json.dumps(report.to_json(), indent=1))
    estimate, model = frequency_comparison(theta, flight, names, report.simulation["g"])
    return [
        path,
        plot_residual_bands(report, out / "residual_bands.png", title=flight.source),
        plot_lag_correlation(report, out / "lag_correlation.png"),
        plot_frequency_response(estimate, model, names, out / "frequency_response.png", title=flight.source),
    ]
