"""Flight-data readers and writers: ``load`` picks the reader from the file's extension or first bytes, ``save``
the writer from the extension."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from ..data.flight import FlightData, FlightDataError
from ._guard import existing_file
from .csv import load_csv as load_csv, save_csv as save_csv
from .mat import load_mat as load_mat
from .mavlink import DEFAULT_PX4 as DEFAULT_PX4, load_log as load_log
from .npz import load_npz as load_npz, save_npz as save_npz
from .ulog import DEFAULT_ULOG as DEFAULT_ULOG, HEADER as ULOG_HEADER, load_ulog as load_ulog

READERS: dict[str, Callable[..., FlightData]] = {
    ".mat": load_mat, ".csv": load_csv, ".npz": load_npz, ".px4log": load_log, ".bin": load_log,
    ".ulg": load_ulog,
}
"""Reader of each known file extension."""

_MAGIC: tuple[tuple[bytes, Callable[..., FlightData]], ...] = (
    (b"MATLAB", load_mat),  # MATLAB v5 header text
    (b"PK\x03\x04", load_npz),  # zip archive
    (b"\xa3\x95\x80", load_log),  # DataFlash/sdlog2 FMT record
    (ULOG_HEADER, load_ulog),  # PX4 ULog header
)


def load(path: str | Path, **options: Any) -> FlightData:
    """Read a flight from ``.mat``, ``.csv``, ``.npz``, ``.px4log``, ``.bin`` or ``.ulg`` (extension first,
    else the file's first bytes); ``options`` go to the reader (:func:`load_mat`, :func:`load_csv`,
    :func:`load_npz`, :func:`load_log`, :func:`load_ulog`; every one takes ``strict``).

    Whatever goes wrong in a reader raises :class:`FlightDataError` (a ``ValueError``) naming the file, or
    ``FileNotFoundError`` when there is no file; implausible data raise unless ``strict=False``
    (:func:`jaxheli.data.plausible.check_plausible`)."""
    path = existing_file(path)
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        try:
            with path.open("rb") as fh:
                head = fh.read(128)
        except OSError as exc:
            raise FlightDataError(f"{path}: cannot be read: {exc}") from exc
        reader = next((r for magic, r in _MAGIC if head.startswith(magic)), None)
        if reader is None and b"time" in head.split(b"\n")[0] and b"," in head:
            reader = load_csv
        if reader is None:
            raise FlightDataError(
                f"{path}: unknown flight-data format (extension '{path.suffix}', first bytes {head[:8].hex(' ')}); "
                f"supported: {', '.join(READERS)}"
            )
    return reader(path, **options)


def save(flight: FlightData, path: str | Path) -> Path:
    """Write ``flight`` as ``.npz`` (:func:`save_npz`) when ``path`` has that extension, else as CSV
    (:func:`save_csv`); returns the path."""
    path = Path(path)
    return (save_npz if path.suffix.lower() == ".npz" else save_csv)(flight, path)
