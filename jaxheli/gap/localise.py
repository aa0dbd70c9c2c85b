"""Where the gap lies: the residual ``measured - simulated`` by channel, frequency band, time window and lag.

The gap of a channel is its normalised residual energy :func:`jaxheli.cost.nmse`,
``sum r^2 / sum (m - mean m)^2``. Every breakdown below splits that number exactly (bands and windows
sum to it), so shares are comparable across channels of different units. The result is a frozen
:class:`~jaxheli.gap.localisation_record.Localisation` (``None`` where a quantity is undefined, e.g. a band with no
Welch bin; ``to_json`` for files).

Closed-loop caveat: a pilot reacts to the helicopter, so the sticks partly follow disturbances; an
input-correlated residual is then not proof of missing structure, only evidence for it.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import scipy.stats

from .._types import Float
from ..cost import nmse, pearson, rmse, tic
from ..data.flight import FlightData
from ..model import INPUT_NAMES
from ..spectra import FrequencyResponse, residual_frequency_response
from .localisation_record import (
    AmplitudeLink, Band, BandCoherence, BandPower, ChannelGap, LagPair, Lags, Localisation, Summary, TopWindow, Windows,
)

DEFAULT_BANDS: tuple[float | None, ...] = (0.0, 0.5, 1.0, 2.0, 5.0, None)
"""Band edges, Hz; ``None`` is the Nyquist frequency."""

_ACTIVE = 1e-12
"""An input is used when its variance exceeds this fraction of the largest input variance."""


def localise(
    flight: FlightData,
    simulated: Float[np.ndarray, "N k"],
    outputs: Sequence[str] | None = None,
    *,
    bands: Sequence[float | None] = DEFAULT_BANDS,
    window_seconds: float = 5.0,
    max_lag_seconds: float = 1.0,
    segment_seconds: float | None = None,
    level: float = 0.95,
) -> Localisation:
    """Localise the gap between ``flight`` and a model's ``simulated[N, k]`` outputs (channels ``outputs``,
    default all of the flight's).

    Args:
        bands: band edges in Hz, from 0 up to ``None`` (Nyquist); bands are ``[lo, hi)``.
        window_seconds: time-window length, s (shortened so the record holds at least 8 windows).
        max_lag_seconds: largest input-residual lag examined, s.
        segment_seconds: Welch segment for the coherence (default :func:`default_segment`).
        level: confidence level of the significance thresholds.

    Returns the gap by channel, band, window and lag, and its summary (see the ``_by_*`` helpers).
    """
    names = tuple(outputs) if outputs is not None else flight.output_names
    meas = flight.select(names).outputs
    sim = np.asarray(simulated, dtype=np.float64)
    if sim.shape != meas.shape:
        raise ValueError(f"localise: simulated {sim.shape} must match {flight.source} outputs {names} {meas.shape}")
    if not np.all(np.isfinite(sim)):
        raise ValueError(f"localise: simulated outputs on {flight.source} are not finite (diverged model?)")
    if not 0.0 < level < 1.0:
        raise ValueError(f"localise: level must be in (0, 1), got {level}")
    variance = np.var(flight.inputs, axis=0)
    active = [i for i in range(len(INPUT_NAMES)) if variance[i] > _ACTIVE * variance.max()]
    if not active:
        raise ValueError(f"localise: every stick of {flight.source} is constant")
    residual = meas - sim
    inputs = flight.inputs[:, active]
    used = tuple(INPUT_NAMES[i] for i in active)
    channel = _by_channel(sim, meas, names)
    band = _by_band(inputs, meas, sim, flight.dt, names, used, bands, segment_seconds, level)
    window = _by_window(flight.time, inputs, residual, meas, names, window_seconds, level)
    lag = _by_lag(inputs, residual, flight.dt, names, used, max_lag_seconds, level)
    return Localisation(flight.source, used, channel, band, window, lag, _summary(channel, band, window, lag, names))


def _by_channel(sim: np.ndarray, meas: np.ndarray, names: tuple[str, ...]) -> dict[str, ChannelGap]:
    """Per channel: ``nmse``, ``share`` of the summed nmse, ``one_minus_rho``, ``tic``, ``rmse`` (units)."""
    gap = np.asarray(nmse(sim, meas))
    rho = np.asarray(pearson(sim, meas))
    theil = np.asarray(tic(sim, meas))
    err = np.asarray(rmse(sim, meas))
    total = gap.sum()
    return {
        n: ChannelGap(nmse=float(gap[c]), share=float(gap[c] / total) if total > 0 else 0.0,
                      one_minus_rho=float(1.0 - rho[c]), tic=float(theil[c]), rmse=float(err[c]))
        for c, n in enumerate(names)
    }


def _periodogram(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided full-record periodogram as mean-square per bin (sums to ``mean(x^2)`` exactly), and freqs."""
    n = x.shape[0]
    X = np.fft.rfft(x, axis=0)
    power = np.abs(X) ** 2 / n**2
    power[1 : (n + 1) // 2] *= 2.0
    return power, np.fft.rfftfreq(n, dt)


def _band_edges(bands: Sequence[float | None], nyquist: float) -> list[tuple[float, float]]:
    edges = [nyquist if e is None else float(e) for e in bands]
    if len(edges) < 2 or edges[0] != 0.0 or edges[-1] < nyquist or np.any(np.diff(edges) <= 0):
        raise ValueError(
            f"localise: bands {list(bands)} must be increasing edges from 0 to None or >= Nyquist ({nyquist:.4g} Hz)"
        )
    return list(zip(edges[:-1], edges[1:]))


def _by_band(inputs, meas, sim, dt, names, used, bands, segment_seconds, level) -> tuple[Band, ...]:
    """Per band ``[lo, hi)`` Hz: residual and measured power (mean square, units^2), ``ratio`` residual over
    measured power, ``nmse_part`` (sums over bands to the channel nmse), ``share`` of the channel's residual
    energy, and the input-residual ``coherence``: the band mean of the multiple coherence, the
    ``coherent_share`` of the band's residual power the inputs explain linearly (power-weighted coherence
    corrected for its bias ``null_mean`` = m / averages, the value for unrelated noise), the per-bin null threshold,
    the fraction of bins above it and a ``verdict`` (``structure`` when most bins are above, ``noise`` when
    few are, else ``mixed``), plus the band-mean partial coherence ``by_input``."""
    edges = _band_edges(bands, 0.5 / dt)
    res_pow, f_full = _periodogram(meas - sim, dt)
    meas_pow, _ = _periodogram(meas - meas.mean(axis=0), dt)
    res_total = res_pow.sum(axis=0)
    meas_total = meas_pow.sum(axis=0)
    frf = residual_frequency_response(inputs, meas, sim, dt, segment_seconds=segment_seconds)
    partial_th, multiple_th = frf.thresholds(level)
    out = []
    for b, (lo, hi) in enumerate(edges):
        last = b == len(edges) - 1
        in_full = (f_full >= lo) & ((f_full <= hi) if last else (f_full < hi))
        per = {}
        for c, n in enumerate(names):
            r, m = res_pow[in_full, c].sum(), meas_pow[in_full, c].sum()
            per[n] = BandPower(
                residual_power=float(r),
                measured_power=float(m),
                ratio=float(r / m) if m > 0 else None,
                nmse_part=float(r / meas_total[c]) if meas_total[c] > 0 else None,
                share=float(r / res_total[c]) if res_total[c] > 0 else 0.0,
            )
        out.append(Band((float(lo), float(hi)), per,
                        _band_coherence(frf, lo, hi, last, names, used, partial_th, multiple_th)))
    return tuple(out)


def _band_coherence(
    frf: FrequencyResponse, lo, hi, last, names, used, partial_th, multiple_th,
) -> dict[str, BandCoherence | None]:
    f = np.asarray(frf.freq)
    sel = (f >= lo) & ((f <= hi) if last else (f < hi))
    if not sel.any():
        return {n: None for n in names}
    multiple = np.asarray(frf.multiple_coherence)[sel]
    partial = np.asarray(frf.coherence)[sel]
    power = np.asarray(frf.output_power)[sel]
    bias = frf.null_mean()
    total = power.sum(axis=0)
    raw = np.where(total > 0, (multiple * power).sum(axis=0) / np.where(total > 0, total, 1.0), 0.0)
    out = {}
    for c, n in enumerate(names):
        above = float(np.mean(multiple[:, c] > multiple_th))
        out[n] = BandCoherence(
            bins=int(sel.sum()),
            multiple_mean=float(multiple[:, c].mean()),
            coherent_share=float(np.clip((raw[c] - bias) / (1.0 - bias), 0.0, 1.0)),
            null_mean=bias,
            threshold=multiple_th,
            above_threshold=above,
            verdict="structure" if above >= 0.5 else ("noise" if above <= 0.2 else "mixed"),
            by_input={i: float(partial[:, c, j].mean()) for j, i in enumerate(used)},
            partial_threshold=partial_th,
        )
    return out


def _fisher_ci(rho: float, n: int, level: float, se_scale: float = 1.0) -> tuple[float, float] | None:
    if n < 5 or abs(rho) >= 1:
        return None
    z = np.arctanh(rho)
    half = scipy.stats.norm.ppf(0.5 + level / 2) * se_scale / np.sqrt(n - 3)
    return float(np.tanh(z - half)), float(np.tanh(z + half))


def _by_window(time, inputs, residual, meas, names, window_seconds, level) -> Windows:
    """Residual energy per time window and its link to input amplitude (the nonlinearity signature).

    ``energy[w][c]`` is the window's part of channel ``c``'s nmse (sums over windows to it); ``share[w]``
    its part of the summed nmse. ``amplitude[w]`` is the RMS of the sticks about their flight means, each
    normalised by its flight RMS (1 = a typical window). ``half_energy_fraction``: the smallest fraction of
    windows holding half of the residual energy (0.5 when spread evenly). ``amplitude_correlation``:
    Spearman's rho between per-sample window energy and amplitude, its p-value and Fisher CI, and the
    log-log ``exponent`` (energy ~ amplitude^exponent) with its CI: about 0 for noise, 2 for missing
    linear structure, above 2 for a residual growing faster than the input (nonlinearity).
    """
    n = time.size
    length = max(2, min(int(round(window_seconds / (time[1] - time[0]))), n // 8))
    count = max(1, n // length)
    bounds = np.round(np.linspace(0, n, count + 1)).astype(int)
    centred = inputs - inputs.mean(axis=0)
    scale = np.sqrt(np.mean(centred**2, axis=0))
    den = np.sum((meas - meas.mean(axis=0)) ** 2, axis=0)
    energy = np.stack([np.sum(residual[a:b] ** 2, axis=0) / den for a, b in zip(bounds[:-1], bounds[1:])])
    amplitude = np.array([np.sqrt(np.mean((centred[a:b] / scale) ** 2)) for a, b in zip(bounds[:-1], bounds[1:])])
    sizes = np.diff(bounds)
    total = energy.sum(axis=1)
    share = total / total.sum() if total.sum() > 0 else np.zeros_like(total)
    order = np.argsort(share)[::-1]
    top = int(order[0])
    half = int(np.searchsorted(np.cumsum(share[order]), 0.5) + 1)
    per_sample = total / sizes
    correlation = {"overall": _amplitude_link(per_sample, amplitude, level)}
    for c, name in enumerate(names):
        correlation[name] = _amplitude_link(energy[:, c] / sizes, amplitude, level)
    return Windows(
        window_s=float(length * (time[1] - time[0])),
        start_s=tuple(float(time[a]) for a in bounds[:-1]),
        energy=tuple({name: float(e[c]) for c, name in enumerate(names)} for e in energy),
        share=tuple(share.tolist()),
        amplitude=tuple(amplitude.tolist()),
        top=TopWindow(top, float(time[bounds[top]]), float(time[bounds[top + 1] - 1]), float(share[top])),
        half_energy_fraction=float(half / count),
        amplitude_correlation=correlation,
    )


def _amplitude_link(energy: np.ndarray, amplitude: np.ndarray, level: float) -> AmplitudeLink:
    count = energy.size
    if count < 5 or np.ptp(amplitude) <= 0 or np.ptp(energy) <= 0:
        return AmplitudeLink(None, None, None, None, None, significant=False, windows=int(count))
    rho, p = scipy.stats.spearmanr(energy, amplitude)
    fit = scipy.stats.linregress(np.log(amplitude), np.log(np.maximum(energy, np.finfo(float).tiny)))
    t = scipy.stats.t.ppf(0.5 + level / 2, count - 2)
    return AmplitudeLink(
        spearman=float(rho),
        p_value=float(p),
        ci=_fisher_ci(float(rho), count, level, se_scale=np.sqrt(1.06)),
        exponent=float(fit.slope),
        exponent_ci=(float(fit.slope - t * fit.stderr), float(fit.slope + t * fit.stderr)),
        significant=bool(p < 1.0 - level and rho > 0),
        windows=int(count),
    )


@jax.jit
def _cross_correlation(u: jnp.ndarray, r: jnp.ndarray, lags: jnp.ndarray) -> tuple[jnp.ndarray, ...]:
    """Normalised ``rho[lag, m, k] = mean u_m(t) r_k(t + lag)`` and autocorrelations ``[lag, m]``, ``[lag, k]``."""
    n = u.shape[0]
    u = (u - u.mean(axis=0, keepdims=True)) / u.std(axis=0, keepdims=True)
    spread = r.std(axis=0, keepdims=True)
    r = (r - r.mean(axis=0, keepdims=True)) / jnp.where(spread > 0, spread, 1.0)
    size = 2 * n
    U = jnp.fft.rfft(u, size, axis=0)
    R = jnp.fft.rfft(r, size, axis=0)
    cross = jnp.fft.irfft(jnp.conj(U)[:, :, None] * R[:, None, :], size, axis=0) / n
    auto_u = jnp.fft.irfft(jnp.abs(U) ** 2, size, axis=0) / n
    auto_r = jnp.fft.irfft(jnp.abs(R) ** 2, size, axis=0) / n
    idx = jnp.where(lags >= 0, lags, size + lags)
    return cross[idx], auto_u[idx], auto_r[idx]


def _by_lag(inputs, residual, dt, names, used, max_lag_seconds, level) -> Lags:
    """Input-residual cross-correlation per (input, channel) over lags ``-L..L`` (positive: the residual
    follows the input). ``peak`` is the largest ``|rho|`` at lags >= 0 (the delay signature: a missing
    path with delay d peaks at d; a model lacking a pure delay shows a negative lobe near 0 and a positive
    one near d). ``threshold``: the Bartlett standard error for independent series (using both
    autocorrelations), times the normal quantile Bonferroni-corrected over the causal lags."""
    n = residual.shape[0]
    count = int(min(round(max_lag_seconds / dt), n // 4))
    lags = np.arange(-count, count + 1)
    cross, auto_u, auto_r = (np.asarray(a) for a in _cross_correlation(jnp.asarray(inputs), jnp.asarray(residual),
                                                                       jnp.asarray(lags)))
    bartlett = np.einsum("lm,lk->mk", auto_u, auto_r) / n
    z = scipy.stats.norm.ppf(1.0 - (1.0 - level) / (2 * (count + 1)))
    causal = lags >= 0
    pairs = {}
    for j, i in enumerate(used):
        for c, name in enumerate(names):
            curve = cross[causal, j, c]
            at = int(np.argmax(np.abs(curve)))
            threshold = float(z * np.sqrt(max(bartlett[j, c], 1.0 / n)))
            pair = LagPair(
                input=i, channel=name,
                peak_lag_s=float(lags[causal][at] * dt), peak_value=float(curve[at]),
                threshold=threshold, significant=bool(abs(curve[at]) > threshold),
                curve=tuple(cross[:, j, c].tolist()),
            )
            pairs[pair.name] = pair
    return Lags(tuple((lags * dt).tolist()), pairs)


def _summary(
    channel: dict[str, ChannelGap], band: tuple[Band, ...], window: Windows, lag: Lags, names: tuple[str, ...],
) -> Summary:
    """The headline: worst channel, its worst band, the top window, the strongest significant lag."""
    worst = max(names, key=lambda n: channel[n].nmse)
    shares = [b.channels[worst].share for b in band]
    where = int(np.argmax(shares))
    coherence = band[where].coherence[worst]
    return Summary(
        worst_channel=worst,
        worst_channel_nmse=channel[worst].nmse,
        worst_band_hz=band[where].range_hz,
        worst_band_share=shares[where],
        worst_band_verdict=None if coherence is None else coherence.verdict,
        top_window_s=(window.top.start_s, window.top.stop_s),
        top_window_share=window.top.share,
        amplitude_link=window.amplitude_correlation["overall"].significant,
        strongest_lag=max(lag.pairs.values(), key=lambda p: abs(p.peak_value) / p.threshold),
    )
