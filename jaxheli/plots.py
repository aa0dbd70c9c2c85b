"""PNG plots of identification results: time-domain verification, convergence curves, flight against model
frequency responses.

Figures are drawn on matplotlib's Agg canvas outside pyplot, so plotting works headless and leaves the
caller's backend and open figures alone.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator, NullFormatter

from .model import INPUT_NAMES, STATE_UNITS
from .spectra import FrequencyResponse

PRIMARY_PAIRS: tuple[tuple[str, str], ...] = (
    ("lat", "p"), ("lat", "phi"), ("lat", "v"), ("lon", "q"), ("lon", "theta"), ("lon", "u"),
    ("ped", "r"), ("col", "w"),
)
"""On-axis (input, output) pairs plotted by default, as in rotorcraft frequency-domain practice."""


def plot_time_domain(
    time: np.ndarray,
    measured: np.ndarray,
    simulated: Mapping[str, np.ndarray],
    names: tuple[str, ...] | list[str],
    path: str | Path,
    title: str = "",
) -> Path:
    """Measured against model outputs, one panel per channel (the paper's Figs. 4-6).

    ``measured`` is ``[N, k]``; each value of ``simulated`` is ``[N, k]`` labelled by its key.
    """
    names = list(names)
    fig, axes = _subplots(len(names), 1, figsize=(10, 1.9 * len(names) + 0.6), sharex=True, squeeze=False)
    for c, (ax, name) in enumerate(zip(axes[:, 0], names)):
        ax.plot(time, measured[:, c], color="black", lw=0.8, label="flight")
        for label, sim in simulated.items():
            ax.plot(time, np.asarray(sim)[:, c], lw=0.9, label=label)
        ax.set_ylabel(f"{name} [{STATE_UNITS.get(name, '-')}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8, ncol=len(simulated) + 1)
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def plot_convergence(
    histories: Mapping[str, np.ndarray],
    path: str | Path,
    title: str = "",
    polish: Mapping[str, Sequence[Sequence[float]]] | None = None,
) -> Path:
    """Best cost per generation (log scale), one curve per label (e.g. per trial or method); with ``polish``
    (``{label: [[start, end] of each round]}``, the polish's own objective), a second panel goes on with the polish
    rounds, each drawn from its start to its end."""
    panels = int(bool(histories)) + int(bool(polish))
    fig, axes = _subplots(1, panels, figsize=(7 + 4 * (panels - 1), 4), squeeze=False)
    if histories:
        ax = axes[0, 0]
        for label, history in histories.items():
            h = np.asarray(history, dtype=float)
            ax.plot(np.arange(1, h.size + 1), h, lw=1.0, label=label)
        _log_panel(ax, "generation", "best cost (paper Eq. 7)", len(histories) <= 12)
    if polish:
        ax = axes[0, -1]
        for j, (label, rounds) in enumerate(polish.items()):
            for k, ends in enumerate(rounds):
                ax.plot([k, k + 1], ends, color=f"C{j % 10}", marker="o", lw=1.2, label=None if k else label)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        _log_panel(ax, "polish round", "polish objective (its own)", True)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _log_panel(ax: Any, xlabel: str, ylabel: str, legend: bool) -> None:
    """Log-scale y, axis labels, grid and (when ``legend``) a legend on one convergence panel; curves that hardly
    move get a decade around them, not an axis spanning their rounding errors."""
    ax.set_yscale("log")
    values = np.concatenate([np.asarray(line.get_ydata(), dtype=float) for line in ax.get_lines()])
    values = values[np.isfinite(values) & (values > 0)]
    if values.size and values.max() < 1.01 * values.min():
        ax.set_ylim(values.min() / 3, values.max() * 3)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3, which="both")
    if legend:
        ax.legend(fontsize=8)


def _decibels(response: np.ndarray) -> np.ndarray:
    """``20 log10 |H|``; NaN (not drawn) where ``H`` is zero, e.g. for a stick that never moves."""
    magnitude = np.abs(response)
    return np.where(magnitude > 0, 20 * np.log10(np.where(magnitude > 0, magnitude, 1.0)), np.nan)


def plot_frequency_response(
    flight: FrequencyResponse,
    model: np.ndarray | Mapping[str, np.ndarray] | None,
    output_names: Sequence[str],
    path: str | Path,
    *,
    input_names: Sequence[str] = INPUT_NAMES,
    pairs: Sequence[tuple[str, str]] | None = None,
    title: str = "",
    band: tuple[float, float] | None = None,
    min_coherence: float | None = None,
    notes: Mapping[tuple[str, str], str] | None = None,
) -> Path:
    """Bode plots of the flight estimate (dots, opacity = coherence) against the model (``[F, k, m]`` line, or
    several models as ``{label: [F, k, m]}``, one line each), one column per (input, output) pair: magnitude
    (dB), phase (deg), partial coherence. ``band`` (Hz) limits the frequency axis, ``min_coherence`` is drawn as
    a dashed line, ``notes`` adds text to a pair's title (e.g. its cost J)."""
    outputs, inputs = list(output_names), list(input_names)
    chosen = [p for p in (PRIMARY_PAIRS if pairs is None else pairs) if p[0] in inputs and p[1] in outputs]
    if not chosen:
        raise ValueError(f"plot_frequency_response: no pair of {pairs or PRIMARY_PAIRS} in {inputs} x {outputs}")
    models = {} if model is None else dict(model) if isinstance(model, Mapping) else {"model": model}
    f = np.asarray(flight.freq)
    fig, axes = _subplots(3, len(chosen), figsize=(2.8 * len(chosen) + 0.5, 7), sharex=True, squeeze=False)
    for c, (i, o) in enumerate(chosen):
        k, m = outputs.index(o), inputs.index(i)
        H = np.asarray(flight.response)[:, k, m]
        gamma = np.clip(np.asarray(flight.coherence)[:, k, m], 0, 1)
        colours = np.zeros((f.size, 4))
        colours[:, 3] = 0.15 + 0.85 * gamma
        axes[0, c].scatter(f, _decibels(H), s=6, c=colours, label="flight")
        axes[1, c].scatter(f, np.degrees(np.angle(H)), s=6, c=colours)
        for j, (label, response) in enumerate(models.items()):
            Hm = np.asarray(response)[:, k, m]
            colour = "C3" if len(models) == 1 else f"C{j % 10}"  # the time-domain plots' colours
            axes[0, c].plot(f, _decibels(Hm), color=colour, lw=1.2, label=label)
            axes[1, c].plot(f, np.degrees(np.angle(Hm)), color=colour, lw=1.2)
        axes[2, c].plot(f, gamma, color="C2", lw=1.0)
        axes[2, c].set_ylim(0, 1.02)
        if min_coherence is not None:
            axes[2, c].axhline(min_coherence, color="grey", ls="--", lw=0.8)
        axes[0, c].set_title(f"{i} -> {o}" + (f" ({notes[(i, o)]})" if notes and (i, o) in notes else ""),
                             fontsize=9)
        axes[2, c].set_xlabel("frequency [Hz]")
        for ax in axes[:, c]:
            ax.set_xscale("log")
            ax.grid(alpha=0.3, which="both")
            if band is not None:
                ax.set_xlim(*band)
                ax.xaxis.set_minor_formatter(NullFormatter())  # under two decades matplotlib labels minor ticks
    axes[0, 0].set_ylabel("magnitude [dB]")
    axes[1, 0].set_ylabel("phase [deg]")
    axes[2, 0].set_ylabel("partial coherence")
    axes[0, 0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _subplots(*args, figsize: tuple[float, float], **kwargs) -> tuple[Figure, Any]:
    """``matplotlib.pyplot.subplots`` without pyplot: a figure of ``figsize`` (inches) on its own Agg canvas."""
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(*args, **kwargs)


def _save(fig: Figure, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
