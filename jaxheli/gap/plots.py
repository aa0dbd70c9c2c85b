"""PNG plots of the gap: residual by band and input-residual lag correlation (flight against model Bode plots:
:func:`jaxheli.plots.plot_frequency_response`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

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
