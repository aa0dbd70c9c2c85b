"""PNG plots of the gap: residual by band, input-residual lag correlation, flight against model Bode plots."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..model import INPUT_NAMES
from ..plots import _save, _subplots
from .frequency import FrequencyResponse

PRIMARY_PAIRS: tuple[tuple[str, str], ...] = (
    ("lat", "p"), ("lat", "phi"), ("lat", "v"), ("lon", "q"), ("lon", "theta"), ("lon", "u"),
    ("ped", "r"), ("col", "w"),
)
"""On-axis (input, output) pairs plotted by default, as in rotorcraft frequency-domain practice."""


def plot_residual_bands(localisation: Mapping[str, object], path: str | Path, title: str = "") -> Path:
    """Left: each channel's residual energy split by band (stacked shares, total nmse above the bar).
    Right: band-mean input-residual multiple coherence (cells above the null threshold are marked)."""
    bands = localisation["band"]
    names = list(localisation["channel"])
    labels = [f"{lo:g}-{hi:.3g} Hz" for lo, hi in (b["range_hz"] for b in bands)]
    shares = np.array([[b["channels"][n]["share"] for n in names] for b in bands])
    coh = np.array([[np.nan if b["coherence"][n] is None else b["coherence"][n]["multiple_mean"] for n in names]
                    for b in bands])
    above = np.array([[b["coherence"][n] is not None and b["coherence"][n]["verdict"] == "structure" for n in names]
                      for b in bands])
    fig, (left, right) = _subplots(1, 2, figsize=(12, 4.2))
    x = np.arange(len(names))
    bottom = np.zeros(len(names))
    for label, share in zip(labels, shares):
        left.bar(x, share, bottom=bottom, label=label)
        bottom += share
    for i, n in enumerate(names):
        left.text(i, 1.02, f"{localisation['channel'][n]['nmse']:.3g}", ha="center", fontsize=8)
    left.set_xticks(x, names)
    left.set_ylim(0, 1.12)
    left.set_ylabel("share of residual energy (nmse above)")
    left.legend(fontsize=7, loc="lower right")
    image = right.imshow(coh, vmin=0, vmax=1, cmap="viridis", aspect="auto")
    for (r, c), flag in np.ndenumerate(above):
        if flag:
            right.text(c, r, "*", ha="center", va="center", color="white")
    right.set_xticks(x, names)
    right.set_yticks(np.arange(len(labels)), labels)
    right.set_title("input-residual coherence (* structure)", fontsize=9)
    fig.colorbar(image, ax=right, fraction=0.04)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def plot_lag_correlation(localisation: Mapping[str, object], path: str | Path, title: str = "") -> Path:
    """Input-residual cross-correlation against lag, one panel per (input, channel), with the significance
    band and the causal peak marked."""
    lag = localisation["lag"]
    lags = np.asarray(lag["lags_s"])
    inputs = list(localisation["inputs"])
    names = list(localisation["channel"])
    fig, axes = _subplots(len(inputs), len(names), figsize=(1.9 * len(names) + 1, 1.6 * len(inputs) + 0.8),
                             sharex=True, sharey=True, squeeze=False)
    for (r, i), (c, n) in ((a, b) for a in enumerate(inputs) for b in enumerate(names)):
        pair = lag["pairs"][f"{i}->{n}"]
        ax = axes[r, c]
        ax.plot(lags, pair["curve"], lw=0.8, color="C0")
        ax.axhspan(-pair["threshold"], pair["threshold"], color="grey", alpha=0.25, lw=0)
        ax.plot(pair["peak_lag_s"], pair["peak_value"], "o", ms=4, color="C3" if pair["significant"] else "grey")
        ax.axvline(0.0, color="black", lw=0.5)
        ax.grid(alpha=0.3)
        if r == 0:
            ax.set_title(n, fontsize=9)
        if c == 0:
            ax.set_ylabel(i)
    for ax in axes[-1]:
        ax.set_xlabel("lag [s]")
    fig.suptitle(title or "input-residual cross-correlation (grey: not significant)", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


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
) -> Path:
    """Bode plots of the flight estimate (dots, opacity = coherence) against the model (``[F, k, m]`` line, or
    several models as ``{label: [F, k, m]}``, one line each), one column per (input, output) pair: magnitude
    (dB), phase (deg), partial coherence."""
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
        axes[0, c].set_title(f"{i} -> {o}", fontsize=9)
        axes[2, c].set_xlabel("frequency [Hz]")
        for ax in axes[:, c]:
            ax.set_xscale("log")
            ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("magnitude [dB]")
    axes[1, 0].set_ylabel("phase [deg]")
    axes[2, 0].set_ylabel("partial coherence")
    axes[0, 0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)
