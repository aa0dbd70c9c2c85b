"""Preprocessing of flight records: pure functions ``FlightData -> FlightData``.

Every function returns a new record and appends one entry ``{"step": name, ...}`` to
``metadata["preprocessing"]``, so a record carries the history of what was done to it.
"""

from __future__ import annotations

from typing import Any, Literal, Sequence

import numpy as np
import scipy.signal

from .flight import FlightData, FlightDataError
from ..model import INPUT_NAMES


def _step(flight: FlightData, record: dict[str, Any], **changes: Any) -> FlightData:
    """A copy of ``flight`` with ``changes`` applied and ``record`` appended to its preprocessing log."""
    meta = dict(flight.metadata)
    meta["preprocessing"] = [*meta.get("preprocessing", []), record]
    return flight.replace(metadata=meta, **changes)


def _grid(t0: float, t1: float, dt: float, where: str) -> np.ndarray:
    """Uniform times ``t0, t0 + dt, ...`` not beyond ``t1`` (s)."""
    if not np.isfinite(dt) or dt <= 0:
        raise FlightDataError(f"{where}: field 'dt': sample time must be a positive number of seconds, got {dt}")
    n = int(np.floor((t1 - t0) / dt + 1e-9)) + 1
    if n < 2:
        raise FlightDataError(f"{where}: field 'time': span {t1 - t0:.6g} s holds fewer than 2 samples of {dt:.6g} s")
    return t0 + dt * np.arange(n)


def _interp(grid: np.ndarray, time: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation of every column of ``values [N, k]`` onto ``grid``."""
    out = np.empty((grid.size, values.shape[1]))
    for j in range(values.shape[1]):
        out[:, j] = np.interp(grid, time, values[:, j])
    return out


def from_samples(
    time: np.ndarray,
    inputs: np.ndarray,
    outputs: np.ndarray,
    names: Sequence[str],
    source: str = "<memory>",
    dt: float | None = None,
    metadata: dict[str, Any] | None = None,
) -> FlightData:
    """Build a uniformly sampled record from unevenly timed raw samples by linear interpolation.

    ``time [N]`` s strictly increasing; ``inputs [N, 4]``; ``outputs [N, k]`` named by ``names``;
    ``dt`` the new sample time in s (default: the median step of ``time``). The grid starts at ``time[0]``.
    """
    time = np.asarray(time, dtype=np.float64)
    inputs = np.asarray(inputs, dtype=np.float64)
    outputs = np.asarray(outputs, dtype=np.float64)
    if time.ndim != 1 or time.size < 2:
        raise FlightDataError(f"{source}: field 'time': expected a 1-D array of >= 2 samples, got shape {time.shape}")
    for field, arr in (("inputs", inputs), ("outputs", outputs)):
        if arr.ndim != 2 or arr.shape[0] != time.size:
            raise FlightDataError(f"{source}: field '{field}': expected {time.size} rows, got shape {arr.shape}")
    steps = np.diff(time)
    if (steps <= 0).any():
        row = int(np.argmax(steps <= 0)) + 1
        raise FlightDataError(
            f"{source}: field 'time': not strictly increasing at sample {row} "
            f"({time[row - 1]:.6g} -> {time[row]:.6g} s)"
        )
    dt = float(np.median(steps)) if dt is None else float(dt)
    grid = _grid(time[0], time[-1], dt, source)
    meta = dict(metadata or {})
    record = {"step": "from_samples", "dt": dt, "raw_samples": int(time.size)}
    meta["preprocessing"] = [*meta.get("preprocessing", []), record]
    return FlightData(grid, _interp(grid, time, inputs), _interp(grid, time, outputs), tuple(names), source, meta)


def resample(flight: FlightData, dt: float) -> FlightData:
    """Linear interpolation onto a new uniform grid of step ``dt`` (s) from the first sample.

    Downsampling does not filter: call :func:`lowpass` below the new Nyquist rate first.
    """
    grid = _grid(flight.time[0], flight.time[-1], float(dt), flight.source)
    return _step(
        flight, {"step": "resample", "dt": float(dt), "from_dt": flight.dt},
        time=grid, inputs=_interp(grid, flight.time, flight.inputs),
        outputs=_interp(grid, flight.time, flight.outputs),
    )


def lowpass(flight: FlightData, cutoff_hz: float, order: int = 4, include_inputs: bool = True) -> FlightData:
    """Zero-phase Butterworth low-pass (``butter`` + ``sosfiltfilt``) of the outputs (and inputs).

    ``cutoff_hz`` is the -3 dB frequency of one pass (Hz); the forward-backward pass squares the gain.
    """
    nyquist = 0.5 / flight.dt
    if not 0 < cutoff_hz < nyquist:
        raise FlightDataError(
            f"{flight.source}: field 'cutoff_hz': {cutoff_hz} Hz must lie in (0, {nyquist:.6g}) Hz (Nyquist)"
        )
    sos = scipy.signal.butter(order, cutoff_hz, fs=1.0 / flight.dt, output="sos")
    padlen = 3 * (2 * len(sos) + 1)
    if flight.n_samples <= padlen:
        raise FlightDataError(
            f"{flight.source}: field 'time': {flight.n_samples} samples are too few for an order-{order} "
            f"zero-phase filter (need > {padlen})"
        )
    inputs = scipy.signal.sosfiltfilt(sos, flight.inputs, axis=0) if include_inputs else flight.inputs
    outputs = scipy.signal.sosfiltfilt(sos, flight.outputs, axis=0)
    record = {"step": "lowpass", "cutoff_hz": float(cutoff_hz), "order": int(order), "zero_phase": True,
              "include_inputs": include_inputs}
    return _step(flight, record, inputs=inputs, outputs=outputs)


SAMPLES_PER_PERIOD = 8
"""Samples per period of a low-passed record's cut-off frequency at which it is fitted (:func:`bandwidth_step`):
system identification practice (CIFER, SIDPAC) fits at 5-10 times the bandwidth."""


def bandwidth_step(flight: FlightData, samples_per_period: int = SAMPLES_PER_PERIOD) -> float | None:
    """The step (s) at which a low-passed record is fitted: the largest whole multiple of its own step within
    ``1 / (samples_per_period f_c)``, ``f_c`` the lowest cut-off (Hz) its preprocessing applied to inputs and outputs
    (:func:`lowpass`); ``None`` when it was not low-passed so, or that multiple is 1 (flight A low-passed at 3 Hz
    and sampled at 126 Hz: 5 steps, 0.040 s)."""
    cutoff = input_cutoff(flight)
    if cutoff is None:
        return None
    multiple = int(np.floor(1.0 / (samples_per_period * cutoff * flight.dt) + 1e-9))
    return multiple * flight.dt if multiple >= 2 else None


def input_cutoff(flight: FlightData) -> float | None:
    """The lowest cut-off (Hz) the record's preprocessing applied to its inputs and outputs alike (:func:`lowpass`
    with ``include_inputs``), ``None`` when its sticks were never low-passed."""
    cutoffs = [float(s["cutoff_hz"]) for s in flight.metadata.get("preprocessing", [])
               if s.get("step") == "lowpass" and s.get("include_inputs", True)]
    return min(cutoffs) if cutoffs else None


def trim(
    flight: FlightData,
    start: float | None = None,
    stop: float | None = None,
    drop_samples: int | tuple[int, int] = 0,
) -> FlightData:
    """Keep samples with ``start <= time <= stop`` (s, on the record's own time axis), then drop
    ``drop_samples`` samples at each end (or ``(head, tail)``), e.g. 50 to remove resampling ringing."""
    head, tail = (drop_samples, drop_samples) if isinstance(drop_samples, int) else drop_samples
    if head < 0 or tail < 0:
        raise FlightDataError(f"{flight.source}: field 'drop_samples': must be >= 0, got {drop_samples}")
    keep = np.ones(flight.n_samples, dtype=bool)
    if start is not None:
        keep &= flight.time >= start
    if stop is not None:
        keep &= flight.time <= stop
    idx = np.flatnonzero(keep)[head:]
    idx = idx[: idx.size - tail]
    if idx.size < 2:
        raise FlightDataError(
            f"{flight.source}: field 'time': trim(start={start}, stop={stop}, drop_samples={drop_samples}) "
            f"leaves {idx.size} samples of {flight.n_samples} ({flight.time[0]:.6g}..{flight.time[-1]:.6g} s)"
        )
    record = {"step": "trim", "start": start, "stop": stop, "drop_samples": [head, tail],
              "first_index": int(idx[0]), "n_samples": int(idx.size)}
    return _step(flight, record, time=flight.time[idx], inputs=flight.inputs[idx], outputs=flight.outputs[idx])


def detrend(
    flight: FlightData,
    kind: Literal["constant", "linear"] = "constant",
    channels: Sequence[str] | None = None,
) -> FlightData:
    """Remove the mean (``"constant"``) or a least-squares line (``"linear"``) from named channels.

    ``channels`` may name outputs and inputs (``lat lon ped col``); default: every output. The removed
    constant offsets are recorded for ``"constant"``.
    """
    if kind not in ("constant", "linear"):
        raise FlightDataError(f"{flight.source}: field 'kind': expected 'constant' or 'linear', got {kind!r}")
    names = list(flight.output_names if channels is None else channels)
    known = (*flight.output_names, *INPUT_NAMES)
    unknown = [c for c in names if c not in known]
    if unknown:
        raise FlightDataError(f"{flight.source}: field 'channels': {unknown} not in the flight (has {known})")
    inputs, outputs = flight.inputs.copy(), flight.outputs.copy()
    removed = {}
    for name in names:
        if name in flight.output_names:
            arr, col = outputs, flight.output_names.index(name)
        else:
            arr, col = inputs, INPUT_NAMES.index(name)
        new = scipy.signal.detrend(arr[:, col], type=kind)
        removed[name] = float(np.mean(arr[:, col] - new))
        arr[:, col] = new
    record = {"step": "detrend", "kind": kind, "channels": names}
    if kind == "constant":
        record["offsets"] = removed
    return _step(flight, record, inputs=inputs, outputs=outputs)


def split(flight: FlightData, fraction: float = 0.7) -> tuple[FlightData, FlightData]:
    """Split into contiguous ``(train, validation)`` records: the first ``round(fraction * N)`` samples
    and the rest (time axes kept)."""
    cut = int(round(fraction * flight.n_samples))
    if not 0 < fraction < 1 or cut < 2 or flight.n_samples - cut < 2:
        raise FlightDataError(
            f"{flight.source}: field 'fraction': {fraction} of {flight.n_samples} samples leaves a part "
            f"with fewer than 2 samples (need 0 < fraction < 1)"
        )
    parts = []
    for part, sl in (("train", slice(None, cut)), ("validation", slice(cut, None))):
        record = {"step": "split", "part": part, "fraction": float(fraction), "cut_index": cut}
        parts.append(_step(flight, record, time=flight.time[sl], inputs=flight.inputs[sl],
                           outputs=flight.outputs[sl]))
    return parts[0], parts[1]
