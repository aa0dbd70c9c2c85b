"""PNG plots of identification results: time-domain verification and convergence curves.

Figures are drawn on matplotlib's Agg canvas outside pyplot, so plotting works headless and leaves the
caller's backend and open figures alone.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .model import STATE_UNITS


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


def plot_convergence(histories: Mapping[str, np.ndarray], path: str | Path, title: str = "") -> Path:
    """Best cost per generation (log scale), one curve per label (e.g. per trial or method)."""
    fig, ax = _subplots(figsize=(7, 4))
    for label, history in histories.items():
        h = np.asarray(history, dtype=float)
        ax.plot(np.arange(1, h.size + 1), h, lw=1.0, label=label)
    ax.set_yscale("log")
    ax.set_xlabel("generation")
    ax.set_ylabel("best cost (paper Eq. 7)")
    ax.grid(alpha=0.3, which="both")
    if len(histories) <= 12:
        ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
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
