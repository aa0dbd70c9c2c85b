"""PX4 sdlog2 (``.px4log``) and DataFlash (``.bin``) logs, read with pymavlink's DataFlash parser.

Each channel is a ``(message, field)`` or ``(message, field, scale)`` pair; the reader follows the log's
own ``FMT`` definitions, so older layouts work as long as the mapped fields exist.

Time base: a message carrying ``TimeUS`` (ArduPilot) or ``TimeMS`` is stamped with it; any other message
takes the ``StartTime`` (us) of the latest ``TIME`` record (sdlog2 writes one per logging cycle, before the
records of that cycle); records before the first stamp are skipped. pymavlink's own ``msg._timestamp`` is
not used: without a GPS fix it falls back to an interpolated clock that is not in seconds (in
``sess006/log001.px4log`` it reaches 71 s over a 28.8 s log). Times are seconds since the first stamp.
The file is parsed by ``DFReader_binary``, the class ``mavutil.mavlink_connection`` picks for ``.bin`` and
``.px4log``, called directly so that content, not the extension, decides.

Every channel is interpolated linearly (angles ``phi``/``theta`` across the +-pi seam) onto a uniform grid
over the span where all used messages exist; the default rate is that of the fastest used message.
"""

from __future__ import annotations

import collections
from pathlib import Path
from typing import Any, Literal, Mapping

import numpy as np

from ..data.flight import FlightData, FlightDataError
from ..model import INPUT_NAMES, MEASURABLE
from ._channels import Missing, Series, check_options, on_grid, read_channels
from ._dataflash import Scan, check_head, scan_log
from ._guard import guarded

Channel = tuple[str, str] | tuple[str, str, float]

DEFAULT_PX4: dict[str, Channel] = {
    "u": ("LPOS", "VY"), "v": ("LPOS", "VX"), "w": ("LPOS", "VZ"),
    "p": ("ATT", "RollRate"), "q": ("ATT", "PitchRate"), "r": ("ATT", "YawRate"),
    "phi": ("ATT", "Roll"), "theta": ("ATT", "Pitch"),
    "lat": ("RC", "C0"), "lon": ("RC", "C1"), "ped": ("RC", "C3"), "col": ("RC", "C5"),
}
"""The authors' PX4 mapping (``data/README.md``): RC channels 1, 2, 4, 6 are ``C0 C1 C3 C5``."""

@guarded("DataFlash/sdlog2 (pymavlink)")
def load_log(
    path: str | Path,
    channels: Mapping[str, Channel] | None = None,
    *,
    rate_hz: float | None = None,
    missing_inputs: Literal["error", "zero"] = "error",
    strict: bool = True,
) -> FlightData:
    """Read a flight from a PX4 sdlog2 / DataFlash log.

    ``channels`` maps output names (``MEASURABLE``) and input names (``lat lon ped col``) to log fields;
    every output it names must exist. With the default :data:`DEFAULT_PX4`, outputs whose message or
    field is absent are dropped (listed in ``metadata["dropped"]``). Inputs are always required unless
    ``missing_inputs="zero"``, which fills absent or unmapped sticks with zeros. ``rate_hz`` sets the
    grid rate (Hz). ``strict=False`` loads the readable part of a truncated or corrupt log (noted in
    ``metadata["problems"]``) instead of raising, and records implausible values as warnings
    (:func:`jaxheli.data.plausible.check_plausible`). What pymavlink prints is captured into
    ``metadata["warnings"]`` (or the error), not shown.
    """
    path = Path(path)
    check_options(path, missing_inputs, rate_hz)
    check_head(path)
    explicit = channels is not None
    mapping = _normalise(path, DEFAULT_PX4 if channels is None else channels)
    wanted = collections.defaultdict(set)
    for msg, field, _ in mapping.values():
        wanted[msg].add(field)
    log = scan_log(path, wanted)
    problems = log.problems()
    if log.counts["FMT"] == 0:
        raise FlightDataError(f"{path}: not a DataFlash/sdlog2 log: no FMT record decoded ({'; '.join(problems)})")
    if set(log.counts) <= {"FMT"}:
        raise FlightDataError(
            f"{path}: no data records after {log.counts['FMT']} FMT definitions in {log.size} bytes "
            f"(log empty or truncated)"
        )
    if strict and problems:
        raise FlightDataError(
            f"{path}: {'; '.join(problems)}; pass strict=False (--no-strict) to load the readable part"
        )

    def read(name: str) -> Series:
        msg, field, scale = mapping[name]
        why = _absent(log, msg, field)
        if why is not None:
            raise Missing(why, f"channel '{name}' ({msg}.{field}): {why}")
        return _series(path, log, msg, field, scale)

    series, dropped, zeroed = read_channels(path, mapping, read, missing_inputs=missing_inputs, explicit=explicit)
    grid, inputs, outputs, names = on_grid(path, series, dropped, rate_hz)
    meta: dict[str, Any] = {
        "reader": "mavlink",
        "file": str(path),
        "channels": {n: f"{m}.{f}" + (f" x {s:g}" if s != 1 else "") for n, (m, f, s) in mapping.items()},
        "dropped": dropped,
        "zero_inputs": zeroed,
        "rate_hz": float(1.0 / (grid[1] - grid[0])),
        "time_base": "TimeUS/TimeMS field, else StartTime of the latest TIME record; s since the first stamp",
        "messages": {m: log.counts[m] for m in sorted({m for m, _, _ in mapping.values()} | {"TIME"})},
        "problems": problems,
    }
    return FlightData(grid, inputs, outputs, names, str(path), meta)


def _normalise(path: Path, channels: Mapping[str, Channel]) -> dict[str, tuple[str, str, float]]:
    """``{name: (message, field, scale)}`` with names checked."""
    out = {}
    for name, spec in channels.items():
        if name not in (*MEASURABLE, *INPUT_NAMES):
            raise FlightDataError(f"{path}: channel '{name}': unknown (expected one of {MEASURABLE + INPUT_NAMES})")
        if not isinstance(spec, tuple | list) or len(spec) not in (2, 3):
            raise FlightDataError(f"{path}: channel '{name}': expected (message, field[, scale]), got {spec!r}")
        out[name] = (str(spec[0]), str(spec[1]), float(spec[2]) if len(spec) == 3 else 1.0)
    return out


def _absent(log: Scan, msg: str, field: str) -> str | None:
    """Why ``msg.field`` cannot be used, or None when it can."""
    if not log.counts[msg]:
        found = ", ".join(sorted(log.counts)) or "nothing"
        return f"no {msg} messages in the log (found: {found})"
    if field not in log.columns[msg]:
        return f"message {msg} has no field '{field}' (fields: {', '.join(log.columns[msg])})"
    distinct = len(set(log.stamps[msg]))
    if distinct < 2:
        return f"{msg} messages carry {distinct} distinct time stamp(s); need 2"
    return None


def _series(path: Path, log: Scan, msg: str, field: str, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (s since the log's first stamp, strictly increasing: the last record of equal stamps wins)
    and scaled values of one field."""
    t = np.asarray(log.stamps[msg]) - log.origin
    try:
        v = scale * np.asarray(log.values[msg][field], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FlightDataError(f"{path}: message {msg} field '{field}': not numeric ({exc})") from exc
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0])
        raise FlightDataError(
            f"{path}: message {msg}: time stamps go backwards at record {i + 1} ({t[i]:.6f} -> {t[i + 1]:.6f} s)"
        )
    last = np.r_[np.diff(t) > 0, True]
    return t[last], v[last]
