"""What the log readers (:mod:`~jaxheli.io.mavlink`, :mod:`~jaxheli.io.ulog`) share: the options both take, the
policy for channels a log cannot supply, and the uniform time grid every channel is interpolated onto."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from ..data.flight import FlightDataError
from ..model import INPUT_NAMES, MEASURABLE

Series = tuple[np.ndarray, np.ndarray]
"""Stamps (s, strictly increasing) and values of one channel."""

ANGLES = ("phi", "theta")
"""Channels interpolated as angles (rad), across the +-pi seam."""


class Missing(Exception):
    """A mapped channel the log cannot supply: ``why`` goes to ``metadata["dropped"]``, ``where`` (naming the channel
    and its source) into the error raised when the channel is required."""

    def __init__(self, why: str, where: str) -> None:
        super().__init__(where)
        self.why, self.where = why, where


def check_options(path: Path, missing_inputs: str, rate_hz: float | None) -> None:
    """Raise :class:`FlightDataError` for a ``missing_inputs`` other than ``"error"`` / ``"zero"`` or a
    ``rate_hz`` (Hz) that is not positive."""
    if missing_inputs not in ("error", "zero"):
        raise FlightDataError(f"{path}: option 'missing_inputs': expected 'error' or 'zero', got {missing_inputs!r}")
    if rate_hz is not None and not rate_hz > 0:
        raise FlightDataError(f"{path}: option 'rate_hz': must be > 0 Hz, got {rate_hz}")


def read_channels(
    path: Path, mapped: Mapping[str, object], read: Callable[[str], Series], *, missing_inputs: str, explicit: bool
) -> tuple[dict[str, Series], dict[str, str], list[str]]:
    """Read every output and input channel ``mapped`` names with ``read(name)`` (which raises :class:`Missing` for a
    channel the log cannot supply), in the order ``MEASURABLE`` then ``INPUT_NAMES``.

    An input the log cannot supply, or one ``mapped`` lacks, raises unless ``missing_inputs="zero"`` (then it is
    zero and listed); an output it cannot supply raises when the user's mapping named it (``explicit``), else it is
    dropped. Returns the series read, the reasons of the channels dropped or zeroed, and the zeroed inputs."""
    series: dict[str, Series] = {}
    dropped: dict[str, str] = {}
    zeroed: list[str] = []
    for name in (*MEASURABLE, *INPUT_NAMES):
        is_input = name in INPUT_NAMES
        if name in mapped:
            try:
                series[name] = read(name)
                continue
            except Missing as miss:
                why, where = miss.why, miss.where
        elif is_input:
            why = where = f"input '{name}' has no mapping"
        else:
            continue
        if is_input and missing_inputs == "zero":
            zeroed.append(name)
            dropped[name] = why
        elif is_input or explicit:
            hint = "; pass missing_inputs='zero' (--missing-inputs zero) for zero sticks" if is_input else ""
            raise FlightDataError(f"{path}: {where}{hint}")
        else:
            dropped[name] = why
    return series, dropped, zeroed


def on_grid(
    path: Path, series: Mapping[str, Series], dropped: Mapping[str, str], rate_hz: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """Every series interpolated onto one uniform grid (:func:`grid`): the grid (s), the inputs ``[N, 4]`` (zero where
    absent), the outputs read ``[N, k]`` and their names; raises when no output was read."""
    outputs = tuple(n for n in MEASURABLE if n in series)
    if not outputs:
        raise FlightDataError(f"{path}: no output channel could be read: {dict(dropped) or 'none mapped'}")
    times = grid(path, series, rate_hz)
    cols = {n: interp(times, *series[n], angle=n in ANGLES) for n in series}
    inputs = np.column_stack([cols.get(n, np.zeros(times.size)) for n in INPUT_NAMES])
    return times, inputs, np.column_stack([cols[n] for n in outputs]), outputs


def grid(path: Path, series: Mapping[str, Series], rate_hz: float | None) -> np.ndarray:
    """Uniform times (s) over the span every series covers, at ``rate_hz`` or the fastest series' median rate."""
    start = max(t[0] for t, _ in series.values())
    stop = min(t[-1] for t, _ in series.values())
    dt = 1.0 / rate_hz if rate_hz is not None else min(float(np.median(np.diff(t))) for t, _ in series.values())
    n = int(np.floor((stop - start) / dt + 1e-9)) + 1
    if n < 2:
        raise FlightDataError(
            f"{path}: the mapped messages overlap for {max(stop - start, 0):.4g} s only: fewer than 2 samples at "
            f"{1 / dt:.4g} Hz"
        )
    return start + dt * np.arange(n)


def interp(times: np.ndarray, t: np.ndarray, v: np.ndarray, angle: bool) -> np.ndarray:
    """Linear interpolation; angles (rad) are unwrapped first and wrapped back into (-pi, pi]."""
    if not angle:
        return np.interp(times, t, v)
    return np.angle(np.exp(1j * np.interp(times, t, np.unwrap(v))))
