"""PNG plots of the gap: residual by band, input-residual lag correlation and the predictions before and after an
effect (flight against model Bode plots: :func:`jaxheli.plots.plot_frequency_response`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._types import Float
from ..data.flight import FlightData
from ..plots import _save, _subplots
from .localisation_record import Localisation


def plot_residual_bands(localisation: Localisation, path: str | Path, title: str = "") -> Path:
    """Left: each channel's residual energy split by band (stacked shares, total nmse above the bar).
    Right: band-mean input-residual multiple coherence (cells above the null threshold are marked)."""
    bands = localisation.band
    names = list(localisation.channel)
    labels = [f"{lo:g}-{hi:.3g} Hz" for lo, hi in (b.range_hz for b in bands)]
    shares = np.array([[b.channels[n].share for n in names] for b in bands])
    coh = np.array([[np.nan if b.coherence[n] is None else b.coherence[n].multiple_mean for n in names]
                    for b in bands])
    above = np.array([[b.coherence[n] is not None and b.coherence[n].verdict == "structure" for n in names]
                      for b in bands])
    fig, (left, right) = _subplots(1, 2, figsize=(12, 4.2))
    x = np.arange(len(names))
    bottom = np.zeros(len(names))
    for label, share in zip(labels, shares):
        left.bar(x, share, bottom=bottom, label=label)
        bottom += share
    for i, n in enumerate(names):
        left.text(i, 1.02, f"{localisation.channel[n].nmse:.3g}", ha="center", fontsize=8)
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


def plot_lag_correlation(localisation: Localisation, path: str | Path, title: str = "") -> Path:
    """Input-residual cross-correlation against lag, one panel per (input, channel), with the significance
    band and the causal peak marked."""
    lag = localisation.lag
    lags = np.asarray(lag.lags_s)
    inputs = list(localisation.inputs)
    names = list(localisation.channel)
    fig, axes = _subplots(len(inputs), len(names), figsize=(1.9 * len(names) + 1, 1.6 * len(inputs) + 0.8),
                             sharex=True, sharey=True, squeeze=False)
    for (r, i), (c, n) in ((a, b) for a in enumerate(inputs) for b in enumerate(names)):
        pair = lag.pairs[f"{i}->{n}"]
        ax = axes[r, c]
        ax.plot(lags, pair.curve, lw=0.8, color="C0")
        ax.axhspan(-pair.threshold, pair.threshold, color="grey", alpha=0.25, lw=0)
        ax.plot(pair.peak_lag_s, pair.peak_value, "o", ms=4, color="C3" if pair.significant else "grey")
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


def plot_before_after(
    flight: FlightData, predicted: Float[np.ndarray, "C N k"], labels: Sequence[str], path: str | Path,
) -> Path:
    """Time histories per channel: the flight's measurement and each prediction ``predicted[c]`` (``labels[c]``)."""
    predicted = np.asarray(predicted)
    if predicted.shape[1:] != flight.outputs.shape or predicted.shape[0] != len(labels):
        raise ValueError(f"plot_before_after: predictions {predicted.shape} must be [{len(labels)}, "
                         f"{', '.join(map(str, flight.outputs.shape))}] for {flight.source}")
    k = len(flight.output_names)
    fig, axes = _subplots(k, 1, figsize=(10, 1.6 * k + 0.8), sharex=True, squeeze=False)
    t = flight.time - flight.time[0]
    units = flight.units
    for c, (ax, name) in enumerate(zip(axes[:, 0], flight.output_names)):
        ax.plot(t, flight.outputs[:, c], color="black", lw=1.0, label="measured")
        for i, label in enumerate(labels):
            ax.plot(t, predicted[i, :, c], lw=0.9, color=f"C{i}", label=label)
        ax.set_ylabel(f"{name} [{units.get(name, '-')}]", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=len(labels) + 1, loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(f"{flight.source}: before and after the effect (validation flight)", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)
