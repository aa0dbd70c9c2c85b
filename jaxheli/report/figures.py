"""The report's PNG figures, rendered in memory with the plotting functions of :mod:`jaxheli.plots` and
:mod:`jaxheli.gap.plots`: time-domain verification, flight against model frequency responses, convergence."""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from .._types import Float
from ..flight import FlightData
from ..gap.frequency import FrequencyResponse
from ..initial_state import estimate_x0
from ..model import G_SI
from ..plots import plot_convergence, plot_time_domain
from ..simulate import make_simulator
from .inputs import ResultSource


def simulate_result(result: ResultSource, flight: FlightData, channels: Sequence[str]) -> Float[np.ndarray, "N k"]:
    """Outputs ``[N, k]`` of ``result``'s parameters on ``flight`` for ``channels``, simulated with the result's
    settings (hold, g, segment, scored channels) from a least-squares initial state, as
    :func:`jaxheli.evaluate` scored it (so the simulator compiled for the scores serves the plots too)."""
    s = result.settings
    scored = tuple(c for c in s.get("outputs") or () if c in flight.output_names)
    sim_channels = scored if set(channels) <= set(scored) else tuple(channels)
    opts = {"outputs": sim_channels, "hold": s.get("hold", "zoh"), "g": s.get("g", G_SI), "segment": s.get("segment")}
    x0 = estimate_x0(result.params, flight, **opts)
    y = np.asarray(make_simulator(flight, x0=x0, **opts)(result.params))
    return y[:, [sim_channels.index(c) for c in channels]]


def time_domain_png(
    flight: FlightData, channels: Sequence[str], simulated: dict[str, np.ndarray], title: str
) -> bytes:
    """Measured ``channels`` of ``flight`` against each labelled simulation ``[N, k]`` (one panel per channel)."""
    measured = flight.select(tuple(channels)).outputs
    return _render(plot_time_domain, flight.time, measured, simulated, tuple(channels), title=title)


def convergence_png(results: Sequence[ResultSource]) -> bytes | None:
    """Best cost per generation of every trial of every result with a history (``None`` if none has one)."""
    curves = {
        (r.label if r.history.shape[0] == 1 else f"{r.label} trial {k}"): h
        for r in results for k, h in enumerate(r.history) if h.size
    }
    return _render(plot_convergence, curves, title="convergence (best cost per generation)") if curves else None


def frequency_png(
    estimate: FrequencyResponse, models: Mapping[str, np.ndarray], channels: Sequence[str],
    pairs: Sequence[tuple[str, str]], title: str,
) -> bytes:
    """Bode plots (magnitude, phase, partial coherence) of the flight estimate against each model's response
    ``{label: [F, k, 4]}`` on the (input, output) ``pairs`` (:func:`jaxheli.gap.plots.plot_frequency_response`)."""
    from ..gap.plots import plot_frequency_response

    return _render(plot_frequency_response, estimate, models, tuple(channels), pairs=tuple(pairs), title=title)


def _render(plot: Callable[..., Path], *args, **kwargs) -> bytes:
    """Call a plot function of the package (``plot(*args, path, **kwargs)``) and return the PNG it wrote."""
    with tempfile.TemporaryDirectory() as tmp:
        path = plot(*args, Path(tmp) / "figure.png", **kwargs)
        return Path(path).read_bytes()
