"""One pass over a DataFlash / sdlog2 log with pymavlink: record counts, formats, time stamps and the
wanted fields, plus byte accounting that exposes truncation and corruption pymavlink passes over silently.
Time stamps follow the rule documented in :mod:`jaxheli.io.mavlink`.
"""

from __future__ import annotations

import collections
import dataclasses
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..data.flight import FlightDataError

_MAGIC = b"\xa3\x95\x80"  # record header 0xA3 0x95, then type 0x80: the first FMT record
_FMT_LEN = 89


@dataclasses.dataclass
class Scan:
    """What one pass over a log found (stamps in s on the log's clock)."""

    size: int
    counts: collections.Counter = dataclasses.field(default_factory=collections.Counter)
    columns: dict[str, list[str]] = dataclasses.field(default_factory=dict)
    stamps: dict[str, list[float]] = dataclasses.field(default_factory=lambda: collections.defaultdict(list))
    values: dict[str, dict[str, list[Any]]] = dataclasses.field(
        default_factory=lambda: collections.defaultdict(lambda: collections.defaultdict(list)))
    origin: float | None = None  # first time stamp in the log, s
    end: int = 0  # bytes up to the end of the last complete record
    truncated: bool = False
    skipped: int = 0  # bytes pymavlink skipped as undecodable
    first_skip: int | None = None

    def problems(self) -> list[str]:
        """Truncation and corruption found by the byte accounting."""
        out = []
        if self.truncated:
            out.append(f"file truncated after {self.size} bytes (last complete record ends at byte {self.end})")
        if self.skipped:
            out.append(f"corrupt: {self.skipped} bytes could not be decoded, first at byte {self.first_skip}")
        return out


def check_head(path: Path) -> None:
    """Reject empty, too short or non-DataFlash files before pymavlink sees them."""
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(3)
    if size == 0:
        raise FlightDataError(f"{path}: empty file (0 bytes)")
    if not _MAGIC.startswith(head):
        raise FlightDataError(
            f"{path}: not a DataFlash/sdlog2 log: starts with bytes {head.hex(' ')}, expected a3 95 80 (an FMT record)"
        )
    if size < _FMT_LEN:
        raise FlightDataError(f"{path}: file truncated after {size} bytes (shorter than one FMT record)")


def scan_log(path: Path, wanted: Mapping[str, set[str]]) -> Scan:
    """Read every record; keep stamps and the ``wanted[message]`` fields (NaN where a record lacks one)."""
    from pymavlink import DFReader  # here, not on import: importing pymavlink sets $MAVLINK_DIALECT

    # Built in two steps so that the file a failing constructor opened can still be closed (after the
    # traceback, which pins pymavlink's memoryview of the file, is gone).
    reader = DFReader.DFReader_binary.__new__(DFReader.DFReader_binary)
    failure = None
    try:
        reader.__init__(str(path))
    except Exception as exc:  # pymavlink raises bare Exception on malformed FMT records
        failure = f"{type(exc).__name__}: {exc}"
    if failure is not None:
        for handle in ("data_map", "filehandle"):
            if hasattr(reader, handle):
                getattr(reader, handle).close()
        raise FlightDataError(f"{path}: corrupt log: pymavlink could not index it ({failure})")
    out = Scan(size=reader.data_len)
    clock = None
    try:
        while True:
            before = reader.offset
            msg = reader.recv_msg()
            if msg is None:
                out.end, out.truncated = before, before < reader.data_len  # even a bare 3-byte record header
                break
            gap = reader.offset - msg.fmt.len - before
            if gap > 0:
                out.skipped += gap
                out.first_skip = before if out.first_skip is None else out.first_skip
            name = msg.fmt.name
            out.counts[name] += 1
            out.columns[name] = msg.fmt.columns
            if name == "TIME" and "StartTime" in msg.fmt.colhash:
                clock = msg.StartTime * 1e-6
            stamp = _own_stamp(msg)
            stamp = clock if stamp is None else stamp
            if stamp is not None and out.origin is None:
                out.origin = stamp
            if name in wanted and stamp is not None:
                out.stamps[name].append(stamp)
                for field in wanted[name]:
                    out.values[name][field].append(getattr(msg, field, np.nan))
    finally:
        reader.close()
    return out


def _own_stamp(msg: Any) -> float | None:
    """Seconds from a record's own ``TimeUS``/``TimeMS`` field, if it has one."""
    if "TimeUS" in msg.fmt.colhash:
        return msg.TimeUS * 1e-6
    if "TimeMS" in msg.fmt.colhash:
        return msg.TimeMS * 1e-3
    return None
