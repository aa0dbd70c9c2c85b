"""NPZ round trip of a ``FlightData``: arrays as stored, names and source as strings, metadata as JSON."""

from __future__ import annotations

import json
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from ..data.flight import FlightData, FlightDataError
from ._guard import guarded

_FIELDS = ("time", "inputs", "outputs", "output_names", "source", "metadata")


def _jsonable(value: Any) -> Any:
    """numpy scalars and arrays as plain Python numbers and lists; anything else as its ``str``."""
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    return str(value)


def save_npz(flight: FlightData, path: str | Path) -> Path:
    """Write ``flight`` to exactly ``path`` (through a file handle, so numpy appends no ``.npz``)."""
    path = Path(path)
    with path.open("wb") as fh:
        np.savez(
            fh,
            time=flight.time,
            inputs=flight.inputs,
            outputs=flight.outputs,
            output_names=np.array(flight.output_names, dtype=str),
            source=np.array(flight.source),
            metadata=np.array(json.dumps(flight.metadata, default=_jsonable)),
        )
    return path


@guarded("NPZ")
def load_npz(path: str | Path) -> FlightData:
    """Read a flight written by :func:`save_npz`; errors name ``path`` (the stored ``source`` is kept as the
    flight's source)."""
    path = Path(path)
    bad = (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError)
    try:
        npz = np.load(path, allow_pickle=False)
    except bad as exc:
        raise FlightDataError(f"{path}: not a readable NPZ file: {exc}") from exc
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise FlightDataError(f"{path}: a single .npy array, not an NPZ flight archive")
    try:
        with npz:
            files = list(npz.files)
            arrays = {f: npz[f] for f in files if f in _FIELDS}
    except bad as exc:
        raise FlightDataError(f"{path}: corrupt NPZ member: {exc}") from exc
    missing = [f for f in _FIELDS if f not in arrays]
    if missing:
        raise FlightDataError(f"{path}: field '{missing[0]}' not found (fields: {sorted(files)})")
    try:
        metadata = json.loads(str(arrays["metadata"]))
    except json.JSONDecodeError as exc:
        raise FlightDataError(f"{path}: field 'metadata': not valid JSON: {exc}") from exc
    if not isinstance(metadata, dict):
        raise FlightDataError(f"{path}: field 'metadata': expected a JSON object, got {type(metadata).__name__}")
    names = tuple(str(n) for n in np.atleast_1d(arrays["output_names"]))
    try:
        return FlightData(arrays["time"], arrays["inputs"], arrays["outputs"], names, str(arrays["source"]), metadata)
    except FlightDataError as exc:
        raise FlightDataError(f"{path}: stored flight invalid: {exc}") from None
