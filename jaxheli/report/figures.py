"""The report's PNG figures, rendered in memory with the plotting functions of :mod:`jaxheli.plots`: time-domain
verification, flight against model frequency responses, convergence."""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from ..data.flight import FlightData
from ..spectra import FrequencyResponse
from ..plots import plot_convergence, plot_frequency_response, plot_time_domain
from .inputs import ResultSource


def time_domain_png(
    flight: FlightData, channels: Sequence[str], simulated: dict[str, np.ndarray], title: str
) -> bytes:
    """Measured ``channels`` of ``flight`` against each labelled simulation ``[N, k]`` (one panel per channel)."""
    measured = flight.select(tuple(channels)).outputs
    return _render(plot_time_domain, flight.time, measured, simulated, tuple(channels), title=title)


def convergence_png(results: Sequence[ResultSource]) -> bytes | None:
    """Best cost per generation of every trial of every result with a history, and the polish's objective per
    round of every polished result beside (``None`` if there is neither)."""
    curves = {
        (r.label if r.history.shape[0] == 1 else f"{r.label} trial {k}"): h
        for r in results for k, h in enumerate(r.history) if h.size
    }
    rounds = {f"{r.label} ({polish['objective']})": polish["objective_rounds"]
              for r in results if (polish := r.content.get("polish") or {}).get("objective_rounds")}
    if not curves and not rounds:
        return None
    return _render(plot_convergence, curves, title="convergence (best cost per generation; polish rounds)",
                   polish=rounds)


def frequency_png(
    estimate: FrequencyResponse, models: Mapping[str, np.ndarray], channels: Sequence[str],
    pairs: Sequence[tuple[str, str]], title: str,
) -> bytes:
    """Bode plots (magnitude, phase, partial coherence) of the flight estimate against each model's response
    ``{label: [F, k, 4]}`` on the (input, output) ``pairs`` (:func:`jaxheli.plots.plot_frequency_response`)."""
    return _render(plot_frequency_response, estimate, models, tuple(channels), pairs=tuple(pairs), title=title)


def _render(plot: Callable[..., Path], *args, **kwargs) -> bytes:
    """Call a plot function of the package (``plot(*args, path, **kwargs)``) and return the PNG it wrote."""
    with tempfile.TemporaryDirectory() as tmp:
        path = plot(*args, Path(tmp) / "figure.png", **kwargs)
        return Path(path).read_bytes()
