"""Where a gap lies, as frozen records (:func:`~jaxheli.gap.localise.localise`): by channel, frequency band, time
window and input-residual lag, and the headline summary.

``to_json`` gives the keys and key order of ``localisation.json`` (``jaxheli localise``) and of the ``localisation``
of ``diagnosis.json``; ``from_json`` reads them back. ``None`` marks an undefined quantity (e.g. a band without a
Welch bin), in the records as in the JSON."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

from ._record import _Flat, _json, _maybe, _read, _write


def _each(convert: Callable[[Any], Any], named: Mapping[str, Any]) -> dict[str, Any]:
    return {name: convert(value) for name, value in named.items()}


@dataclasses.dataclass(frozen=True)
class ChannelGap(_Flat):
    """One channel's gap: ``nmse`` (:func:`~jaxheli.cost.nmse`), its ``share`` of the summed nmse, ``one_minus_rho``
    (1 - Pearson's rho), Theil's ``tic`` and ``rmse`` (the channel's units)."""

    nmse: float
    share: float
    one_minus_rho: float
    tic: float
    rmse: float


@dataclasses.dataclass(frozen=True)
class BandPower(_Flat):
    """One channel in one band: residual and measured power (mean square, units^2), their ``ratio``, the band's
    ``nmse_part`` (sums over bands to the channel nmse) and ``share`` of the channel's residual energy (``None``:
    no measured power)."""

    residual_power: float
    measured_power: float
    ratio: float | None
    nmse_part: float | None
    share: float


@dataclasses.dataclass(frozen=True)
class BandCoherence(_Flat):
    """Input-residual coherence of one channel in one band: Welch ``bins``, the band mean of the multiple
    coherence, the ``coherent_share`` of the residual power the inputs explain linearly (bias ``null_mean``
    removed), the per-bin null ``threshold``, the fraction of bins ``above_threshold``, the ``verdict``
    (``structure``, ``mixed`` or ``noise``) and the band-mean partial coherence ``by_input`` with its
    ``partial_threshold``."""

    bins: int
    multiple_mean: float
    coherent_share: float
    null_mean: float
    threshold: float
    above_threshold: float
    verdict: str
    by_input: Mapping[str, float]
    partial_threshold: float


@dataclasses.dataclass(frozen=True)
class Band:
    """One band ``[lo, hi)`` Hz: per channel its power split and input-residual coherence (``None``: no Welch bin
    in the band)."""

    range_hz: tuple[float, float]
    channels: Mapping[str, BandPower]
    coherence: Mapping[str, BandCoherence | None]

    def to_json(self) -> dict[str, Any]:
        """``{range_hz, channels, coherence}``."""
        return {"range_hz": list(self.range_hz), "channels": _each(BandPower.to_json, self.channels),
                "coherence": _each(_json, self.coherence)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Band:
        """The inverse of :meth:`to_json`."""
        return cls(tuple(data["range_hz"]), _each(BandPower.from_json, data["channels"]),
                   _each(partial(_maybe, BandCoherence.from_json), data["coherence"]))


@dataclasses.dataclass(frozen=True)
class AmplitudeLink(_Flat):
    """Window residual energy against input amplitude over ``windows`` windows: Spearman's rho, its p-value and
    Fisher ``ci``, the log-log ``exponent`` (energy ~ amplitude^exponent) with its ``exponent_ci``, and whether the
    link is ``significant`` (all ``None`` where undefined: too few windows or no spread)."""

    spearman: float | None
    p_value: float | None
    ci: tuple[float, float] | None
    exponent: float | None
    exponent_ci: tuple[float, float] | None
    significant: bool
    windows: int


@dataclasses.dataclass(frozen=True)
class TopWindow(_Flat):
    """The window holding the largest share of the residual energy: its ``index``, first and last sample times
    (s) and ``share``."""

    index: int
    start_s: float
    stop_s: float
    share: float


@dataclasses.dataclass(frozen=True)
class Windows:
    """The gap by time window (:func:`~jaxheli.gap.localise._by_window`): window length and starts (s), per window
    the channel nmse parts ``energy``, the ``share`` of the summed nmse and the input ``amplitude``, the ``top``
    window, the ``half_energy_fraction`` and the ``amplitude_correlation`` (``overall`` and per channel)."""

    window_s: float
    start_s: tuple[float, ...]
    energy: tuple[Mapping[str, float], ...]
    share: tuple[float, ...]
    amplitude: tuple[float, ...]
    top: TopWindow
    half_energy_fraction: float
    amplitude_correlation: Mapping[str, AmplitudeLink]

    def to_json(self) -> dict[str, Any]:
        """The fields by name, in field order."""
        return {**_write(self), "top": self.top.to_json(),
                "amplitude_correlation": _each(AmplitudeLink.to_json, self.amplitude_correlation)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Windows:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, top=TopWindow.from_json(data["top"]),
                     amplitude_correlation=_each(AmplitudeLink.from_json, data["amplitude_correlation"]))


@dataclasses.dataclass(frozen=True)
class LagPair(_Flat):
    """Input-residual cross-correlation of one ``input`` and ``channel``: the causal peak (lag, s, and value), the
    significance ``threshold``, whether the peak passes it, and the ``curve`` over :attr:`Lags.lags_s`."""

    input: str
    channel: str
    peak_lag_s: float
    peak_value: float
    threshold: float
    significant: bool
    curve: tuple[float, ...]

    @property
    def name(self) -> str:
        """``input->channel``, its key in :attr:`Lags.pairs`."""
        return f"{self.input}->{self.channel}"


@dataclasses.dataclass(frozen=True)
class Lags:
    """The gap by lag (:func:`~jaxheli.gap.localise._by_lag`): the lags (s) and each ``input->channel`` pair."""

    lags_s: tuple[float, ...]
    pairs: Mapping[str, LagPair]

    def to_json(self) -> dict[str, Any]:
        """``{lags_s, pairs}``."""
        return {"lags_s": list(self.lags_s), "pairs": _each(LagPair.to_json, self.pairs)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Lags:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, pairs=_each(LagPair.from_json, data["pairs"]))


@dataclasses.dataclass(frozen=True)
class Summary:
    """The headline: the worst channel and its nmse, its worst band (Hz), that band's share and coherence verdict
    (``None``: no Welch bin), the top window (s) and its share, whether the residual grows with the input
    amplitude, and the strongest lag pair (written without its curve)."""

    worst_channel: str
    worst_channel_nmse: float
    worst_band_hz: tuple[float, float]
    worst_band_share: float
    worst_band_verdict: str | None
    top_window_s: tuple[float, float]
    top_window_share: float
    amplitude_link: bool
    strongest_lag: LagPair

    def to_json(self) -> dict[str, Any]:
        """The fields by name, in field order."""
        return {**_write(self), "strongest_lag": _write(self.strongest_lag, "curve")}

    @classmethod
    def from_json(cls, data: Mapping[str, Any], lags: Lags) -> Summary:
        """The inverse of :meth:`to_json`, the strongest pair taken from ``lags``."""
        strongest = data["strongest_lag"]
        return _read(cls, data, strongest_lag=lags.pairs[f"{strongest['input']}->{strongest['channel']}"])


@dataclasses.dataclass(frozen=True)
class Localisation:
    """Where a model misses a flight (:func:`~jaxheli.gap.localise.localise`).

    Attributes:
        source: the flight; ``inputs`` the sticks that move on it.
        channel, band, window, lag: the gap by channel, by frequency band, by time window, by lag.
        summary: the headline.
        frequency_response: per ``input->output`` pair the flight-against-model mismatch
            (:func:`~jaxheli.spectra.mismatch`; ``None`` where undefined), and ``simulation`` how the prediction was
            made (JSON settings); both ``None`` unless the model is known
            (:func:`~jaxheli.gap.compare.localise_prediction`).
    """

    source: str
    inputs: tuple[str, ...]
    channel: Mapping[str, ChannelGap]
    band: tuple[Band, ...]
    window: Windows
    lag: Lags
    summary: Summary
    frequency_response: Mapping[str, Mapping[str, float | None]] | None = None
    simulation: Mapping[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """``localisation.json``: ``{source, inputs, channel, band, window, lag, summary}`` and, where known,
        ``frequency_response`` and ``simulation``."""
        known = {} if self.frequency_response is None else {
            "frequency_response": _each(dict, self.frequency_response), "simulation": self.simulation}
        return {"source": self.source, "inputs": list(self.inputs), "channel": _each(ChannelGap.to_json, self.channel),
                "band": [b.to_json() for b in self.band], "window": self.window.to_json(),
                "lag": self.lag.to_json(), "summary": self.summary.to_json(), **known}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Localisation:
        """The inverse of :meth:`to_json` (other keys ignored)."""
        lag = Lags.from_json(data["lag"])
        response = data.get("frequency_response")
        return cls(data["source"], tuple(data["inputs"]), _each(ChannelGap.from_json, data["channel"]),
                   tuple(map(Band.from_json, data["band"])), Windows.from_json(data["window"]), lag,
                   Summary.from_json(data["summary"], lag), _maybe(partial(_each, dict), response),
                   data.get("simulation"))
