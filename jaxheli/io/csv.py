"""CSV flights: a header row, a ``time`` column (s), the four sticks ``lat lon ped col`` and any outputs
among ``u v p q phi theta a b w r`` (state units). Other columns are ignored and listed in the metadata."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ..data.flight import FlightData, FlightDataError
from ..model import INPUT_NAMES, MEASURABLE
from ..data.preprocess import from_samples
from ._guard import guarded


@guarded("CSV")
def load_csv(path: str | Path, *, dt: float | None = None) -> FlightData:
    """Read a CSV flight. Time stamps must increase; with ``dt`` (s) uneven stamps are interpolated onto
    a uniform grid of that step, otherwise they must already be uniform."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise FlightDataError(f"{path}: not a text CSV file: {exc}") from exc
    if not rows:
        raise FlightDataError(f"{path}: empty file: expected a header row with 'time', {', '.join(INPUT_NAMES)}")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in ("time", *INPUT_NAMES) if c not in header]
    if missing:
        raise FlightDataError(f"{path}: line 1: missing column(s) {missing} (header: {header})")
    duplicated = sorted({h for h in header if header.count(h) > 1})
    if duplicated:
        raise FlightDataError(f"{path}: line 1: duplicated column(s) {duplicated}")
    outputs = [c for c in header if c in MEASURABLE]
    if not outputs:
        raise FlightDataError(f"{path}: line 1: no output column (expected some of {MEASURABLE}; header: {header})")
    used = ["time", *INPUT_NAMES, *outputs]
    values, lines = _parse(path, header, used, rows[1:])
    time = values[:, 0]
    back = np.flatnonzero(np.diff(time) <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise FlightDataError(
            f"{path}: line {lines[i]}, column 'time': {time[i]:.9g} s does not increase "
            f"(previous {time[i - 1]:.9g} s)"
        )
    inputs, outs = values[:, 1:5], values[:, 5:]
    meta = {"reader": "csv", "file": str(path), "ignored_columns": [c for c in header if c not in used]}
    if dt is None:
        return FlightData(time, inputs, outs, tuple(outputs), str(path), meta)
    return from_samples(time, inputs, outs, outputs, str(path), dt=dt, metadata=meta)


def _parse(path: Path, header: list[str], used: list[str], rows: list[list[str]]) -> tuple[np.ndarray, list[int]]:
    """Numeric ``[N, len(used)]`` array of the used columns and the file line of each row (blank lines
    skipped); errors name line, column and cell."""
    cols = [header.index(c) for c in used]
    out, lines = [], []
    for line, row in enumerate(rows, start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise FlightDataError(f"{path}: line {line}: {len(row)} cells, but the header has {len(header)} columns")
        vals = []
        for name, j in zip(used, cols):
            try:
                v = float(row[j])
            except ValueError:
                raise FlightDataError(f"{path}: line {line}, column '{name}': not a number: {row[j]!r}") from None
            if not math.isfinite(v):
                raise FlightDataError(f"{path}: line {line}, column '{name}': non-finite value {row[j]!r} (NaN/Inf)")
            vals.append(v)
        out.append(vals)
        lines.append(line)
    if len(out) < 2:
        raise FlightDataError(f"{path}: {len(out)} data rows; need at least 2 samples")
    return np.array(out), lines


def save_csv(flight: FlightData, path: str | Path) -> Path:
    """Write ``time, lat, lon, ped, col, <outputs>`` with full float precision (exact round trip)."""
    path = Path(path)
    header = ",".join(("time", *INPUT_NAMES, *flight.output_names))
    table = np.column_stack([flight.time, flight.inputs, flight.outputs])
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.17g")
    return path
