"""Reader for the authors' MATLAB files (``scipy.io.loadmat``): iddata structs and plain ``inr``/``outr`` arrays.

Known layouts (see ``data/README.md``):

- ``iddata``: a struct with ``OutputData [N, 8]`` = ``u v p q phi theta w r``, ``InputData [N, 4]``,
  ``Ts``, ``Tstart`` (``ppr_data.mat``); time is ``Tstart + Ts * k``.
- ``graphready``: ``inr [N, 4]``, ``outr [N, 10]`` = ``u v p q phi theta a b w r``, ``t`` (``Data_graphready.mat``).
- ``tested``: ``inr [N, 4]``, ``outr [N, 11]`` = ``u v theta phi q p a b AccZ r r_fb``, ``t`` (``tested.mat``).

Columns ``a`` and ``b`` are multiples of the cyclic sticks, not measurements: left out unless
``include_flapping=True``. ``AccZ`` and ``r_fb`` are not model states and are always dropped.
"""

from __future__ import annotations

import warnings
import zlib
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import scipy.io
from scipy.io.matlab import MatReadError

from ..data.flight import FlightData, FlightDataError
from ..model import INPUT_NAMES, MEASURABLE
from ._guard import guarded
from ._matcheck import check_mat

IDDATA_COLUMNS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
OUTR_COLUMNS = {
    10: ("graphready", ("u", "v", "p", "q", "phi", "theta", "a", "b", "w", "r")),
    11: ("tested", ("u", "v", "theta", "phi", "q", "p", "a", "b", "AccZ", "r", "r_fb")),
}
"""Output column names of plain ``outr`` arrays, keyed by their column count. A count alone does not decide:
the layout is taken only when its ``a`` and ``b`` columns are multiples of the ``lon`` and ``lat`` sticks."""

_FLAPPING = ("a", "b")
_STICK_MULTIPLE_TOL = 1e-6
"""Largest misfit of a flapping column to a multiple of its stick, relative to the column's size."""


@guarded("MATLAB")
def load_mat(
    path: str | Path,
    *,
    variables: Mapping[str, str] | None = None,
    columns: Sequence[str] | None = None,
    include_flapping: bool = False,
) -> FlightData:
    """Read one flight from a MATLAB v5 file, detecting its layout.

    ``variables`` overrides detection: ``{"iddata": name}`` for an iddata struct, or
    ``{"inputs": name, "outputs": name, "time": name}`` for plain arrays (inputs ``[N, 4]`` lat lon ped
    col, time in s). ``columns`` names the output columns (names outside ``MEASURABLE`` are dropped); by
    default they come from the detected layout. Outputs are returned in state order (``MEASURABLE``).
    The file's structure is checked before scipy reads it (:mod:`jaxheli.io._matcheck`).
    """
    path = Path(path)
    data, load_notes = _loadmat(path)
    if variables is None:
        variables = _detect(path, data)
    if "iddata" in variables:
        time, inputs, outputs, ts, notes = _from_iddata(path, data, variables["iddata"])
        layout, default_cols = "iddata", IDDATA_COLUMNS
    else:
        time, inputs, outputs = _from_arrays(path, data, variables)
        layout, default_cols = _layout(path, variables, inputs, outputs) if columns is None else ("custom", None)
        ts, notes = round(float(np.median(np.diff(time))), 9), []
    cols = tuple(columns) if columns is not None else default_cols
    out_var = variables.get("iddata", variables.get("outputs"))
    if cols is None or len(cols) != outputs.shape[1]:
        raise FlightDataError(
            f"{path}: variable '{out_var}': {outputs.shape[1]} output columns but "
            f"{'no known layout' if cols is None else f'{len(cols)} column names'}; pass columns= (one name each)"
        )
    keep = sorted(
        (i for i, c in enumerate(cols) if c in MEASURABLE and (include_flapping or c not in _FLAPPING)),
        key=lambda i: MEASURABLE.index(cols[i]),
    )
    meta: dict[str, Any] = {
        "reader": "mat",
        "file": str(path),
        "layout": layout,
        "variables": dict(variables),
        "columns": list(cols),
        "dropped_columns": [c for i, c in enumerate(cols) if i not in keep],
        "Ts": ts,
        "notes": notes + load_notes,
    }
    return FlightData(time, inputs, outputs[:, keep], tuple(cols[i] for i in keep), str(path), meta)


def _loadmat(path: Path) -> tuple[dict[str, Any], list[str]]:
    """All variables of the file, and the texts of any warnings scipy raised while reading it."""
    check_mat(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            data = scipy.io.loadmat(path)
        except (MatReadError, ValueError, NotImplementedError, TypeError, IndexError, OSError, zlib.error) as exc:
            raise FlightDataError(
                f"{path}: not a readable MATLAB v4/v5 file (truncated, corrupt or v7.3): {type(exc).__name__}: {exc}"
            ) from exc
    data = {k: v for k, v in data.items() if not k.startswith("__")}
    if not data:
        raise FlightDataError(f"{path}: no variables in the file (empty or truncated MATLAB file)")
    return data, [f"scipy: {w.message}" for w in caught]


def _detect(path: Path, data: dict[str, Any]) -> dict[str, str]:
    """Variable names of the first known layout found in ``data``."""
    for name, value in data.items():
        fields = value.dtype.names if isinstance(value, np.ndarray) else None
        if fields and {"OutputData", "InputData"} <= set(fields):
            return {"iddata": name}
    missing = [v for v in ("inr", "outr") if v not in data]
    if missing:
        raise FlightDataError(
            f"{path}: variable '{missing[0]}' not found: not a known flight layout (an iddata struct with "
            f"OutputData/InputData, or arrays inr/outr/t); variables present: {sorted(data)}; pass variables="
        )
    return {"inputs": "inr", "outputs": "outr", **({"time": "t"} if "t" in data else {})}


def _get(path: Path, data: Mapping[str, Any], name: str, what: str) -> Any:
    if name not in data:
        raise FlightDataError(f"{path}: variable '{name}' ({what}) not found; variables present: {sorted(data)}")
    return data[name]


def _matrix(path: Path, name: str, value: Any, cols: int | None = None) -> np.ndarray:
    """A real 2-D float array, checked for ``cols`` columns."""
    arr = np.asarray(value)
    if arr.ndim != 2 or not np.issubdtype(arr.dtype, np.number) or (cols is not None and arr.shape[1] != cols):
        want = f"[N, {cols}]" if cols else "[N, k]"
        raise FlightDataError(
            f"{path}: variable '{name}': expected a numeric {want} array, got {arr.dtype} {arr.shape}"
        )
    if np.iscomplexobj(arr):
        raise FlightDataError(f"{path}: variable '{name}': complex values; flight data must be real")
    return arr.astype(np.float64)


def _unwrap(value: Any) -> np.ndarray:
    """The array inside MATLAB's nested one-element object (cell) arrays."""
    arr = np.asarray(value)
    while arr.dtype == object and arr.size == 1:
        arr = np.asarray(arr.item())
    return arr


def _scalar(path: Path, field: str, value: Any, default: float) -> float:
    """A real MATLAB scalar (``default`` when empty); ``field`` names it in errors."""
    arr = _unwrap(value)
    if not arr.size:
        return default
    if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise FlightDataError(
            f"{path}: field '{field}': expected a real number, got {arr.dtype} {arr.reshape(-1)[:3]}"
        )
    return float(arr.reshape(-1)[0])


def _layout(path: Path, variables: Mapping[str, str], inputs: np.ndarray, outputs: np.ndarray):
    """``(layout, columns)`` of a plain ``outr`` array: its column count names a candidate in
    :data:`OUTR_COLUMNS`, taken only if the candidate's ``a`` and ``b`` columns are multiples of the cyclic
    sticks (``a`` of ``lon``, ``b`` of ``lat``) as in the authors' files; ``("custom", None)`` otherwise."""
    if outputs.shape[1] not in OUTR_COLUMNS:
        return "custom", None
    layout, cols = OUTR_COLUMNS[outputs.shape[1]]
    for flap, stick in (("a", "lon"), ("b", "lat")):
        col, x = outputs[:, cols.index(flap)], inputs[:, INPUT_NAMES.index(stick)]
        gain = float(x @ col / (x @ x)) if x @ x > 0 else 0.0
        if np.max(np.abs(col - gain * x)) > _STICK_MULTIPLE_TOL * max(1.0, float(np.max(np.abs(col)))):
            raise FlightDataError(
                f"{path}: variable '{variables['outputs']}': {outputs.shape[1]} columns suggest the '{layout}' "
                f"layout, but its column {cols.index(flap) + 1} ('{flap}') is not a multiple of the '{stick}' "
                f"stick; pass columns= (one name each)"
            )
    return layout, cols


def _from_iddata(path: Path, data: Mapping[str, Any], name: str):
    """``(time, inputs, outputs, Ts, notes)`` of an iddata struct (single experiment)."""
    struct = np.asarray(_get(path, data, name, "iddata struct"))
    fields = struct.dtype.names or ()
    for field in ("OutputData", "InputData", "Ts"):
        if field not in fields:
            raise FlightDataError(f"{path}: variable '{name}' field '{field}' not found (fields: {list(fields)})")
    rec = struct.reshape(-1)[0]
    arrays = {}
    for field in ("OutputData", "InputData"):
        arr = _unwrap(rec[field])
        if arr.dtype == object:
            raise FlightDataError(f"{path}: variable '{name}' field '{field}': {arr.size} experiments; expected 1")
        arrays[field] = arr
    outputs = _matrix(path, f"{name}.OutputData", arrays["OutputData"])
    inputs = _matrix(path, f"{name}.InputData", arrays["InputData"], len(INPUT_NAMES))
    ts = _scalar(path, f"{name}.Ts", rec["Ts"], float("nan"))
    if not ts > 0:
        raise FlightDataError(f"{path}: variable '{name}' field 'Ts': sample time must be > 0 s, got {ts}")
    t0 = _scalar(path, f"{name}.Tstart", rec["Tstart"], 0.0) if "Tstart" in fields else 0.0
    notes = [str(s).strip() for s in np.asarray(rec["Notes"]).reshape(-1)] if "Notes" in fields else []
    time = t0 + ts * np.arange(outputs.shape[0])
    return time, inputs, outputs, ts, [n for n in notes if n]


def _from_arrays(path: Path, data: Mapping[str, Any], variables: Mapping[str, str]):
    """``(time, inputs, outputs)`` of plain arrays named by ``variables``."""
    for key in ("inputs", "outputs"):
        if key not in variables:
            raise FlightDataError(f"{path}: variables= is missing the key '{key}' (got {dict(variables)})")
    inputs = _matrix(path, variables["inputs"], _get(path, data, variables["inputs"], "inputs"), len(INPUT_NAMES))
    outputs = _matrix(path, variables["outputs"], _get(path, data, variables["outputs"], "outputs"))
    if "time" not in variables:
        raise FlightDataError(f"{path}: no time variable: pass variables={{..., 'time': name}}")
    time = _matrix(path, variables["time"], np.atleast_2d(_get(path, data, variables["time"], "time"))).reshape(-1)
    n = {variables["inputs"]: inputs.shape[0], variables["outputs"]: outputs.shape[0], variables["time"]: time.size}
    if len(set(n.values())) != 1:
        raise FlightDataError(f"{path}: variables disagree on the number of samples: {n}")
    return time, inputs, outputs
