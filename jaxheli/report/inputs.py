"""What the report reads: result folders of ``jaxheli identify``, a diagnosis folder or JSON file of
``jaxheli diagnose`` / ``jaxheli check``, and the flights the results name (or ``--data`` gives)."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..data.flight import FlightData
from ..flights import load_flight
from ..model import params_array


@dataclasses.dataclass(frozen=True)
class ResultSource:
    """One identification result as ``jaxheli identify`` saved it.

    Attributes:
        label: name shown in the report (the method, plus the folder when methods repeat).
        folder: the result folder.
        content: ``result.json`` as a dict.
        params: ``[40]`` identified parameters (order of :data:`jaxheli.PARAM_NAMES`).
        history: ``[K, iterations]`` best cost per generation from ``result.npz`` (``[K, 0]`` without one).
        pngs: PNG files saved beside ``result.json``, name -> bytes.
    """

    label: str
    folder: Path
    content: dict[str, Any]
    params: np.ndarray
    history: np.ndarray
    pngs: dict[str, bytes]

    @property
    def settings(self) -> dict[str, Any]:
        """``settings`` of ``result.json`` (simulation options, sources)."""
        return self.content.get("settings") or {}


@dataclasses.dataclass(frozen=True)
class DiagnosisSource:
    """A gap diagnosis: ``diagnosis.json`` (``None`` if only a consistency check was given), its
    ``consistency`` findings (from the diagnosis or ``consistency.json``) and the PNG plots beside it."""

    path: Path
    content: dict[str, Any] | None
    consistency: list[dict[str, Any]] | None
    pngs: dict[str, bytes]


def load_results(paths: Sequence[str | Path]) -> list[ResultSource]:
    """Read result folders or ``result.json`` files; labels are unique (method, or method [folder])."""
    if not paths:
        raise ValueError("report: give at least one RESULT (a folder or result.json of jaxheli identify)")
    loaded = [_load_result(Path(p)) for p in paths]
    methods = [r.content.get("method", "?") for r in loaded]
    return [
        dataclasses.replace(r, label=m if methods.count(m) == 1 else f"{m} [{r.folder.name}]")
        for r, m in zip(loaded, methods)
    ]


def load_diagnosis(path: str | Path) -> DiagnosisSource:
    """Read ``diagnosis.json`` and/or ``consistency.json`` from a folder, or one such JSON file."""
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    files = [folder / "diagnosis.json", folder / "consistency.json"] if path.is_dir() else [path]
    found = [f for f in files if f.is_file()]
    if not found:
        raise FileNotFoundError(f"{path}: no diagnosis.json or consistency.json (run jaxheli diagnose / jaxheli check)")
    content, consistency = None, None
    for f in found:
        data = _read_json(f)
        if isinstance(data, list):
            consistency = consistency or _findings(f, data)
        elif isinstance(data, dict):
            if "ranking" in data and not isinstance(data["ranking"], list):
                kind = type(data["ranking"]).__name__
                raise ValueError(f"{f}: field 'ranking': expected a list of effects, got {kind}")
            content = data
            if data.get("consistency") is not None:
                consistency = _findings(f, data["consistency"])
        else:
            raise ValueError(f"{f}: expected a JSON object (diagnosis) or list (consistency findings)")
    return DiagnosisSource(path, content, consistency, _pngs(folder))


def load_flights(results: Sequence[ResultSource], data: Sequence[str | Path] = ()) -> list[FlightData]:
    """The flights to plot: ``data`` when given (files, or ``default`` for the embedded flight), else each
    result's training and validation flights as fitted (the NPZ files its ``data`` block names, preprocessing
    included), falling back to the source files its settings name where those are missing; each flight once."""
    if data:
        return [load_flight(str(d)) for d in data]
    found: dict[tuple[str, str, int], FlightData] = {}
    for r in results:
        for role in ("train", "validate"):
            saved = (r.content.get("data") or {}).get(role)
            source = r.settings.get(f"{role}_source")
            if saved and (r.folder / saved).is_file():
                flight = load_flight(str(r.folder / saved))
            elif source and Path(source).is_file():
                flight = load_flight(source)
            else:
                continue
            key = (flight.source, json.dumps(flight.metadata.get("preprocessing", []), default=str), flight.n_samples)
            found.setdefault(key, flight)
    return list(found.values())


def recorded_sources(results: Sequence[ResultSource]) -> list[str]:
    """Training and validation sources named in the results' settings, each once, in order."""
    found = (r.settings.get(k) for r in results for k in ("train_source", "validate_source"))
    return list(dict.fromkeys(s for s in found if s))


def _load_result(path: Path) -> ResultSource:
    file = path / "result.json" if path.is_dir() else path
    if not file.is_file():
        raise FileNotFoundError(f"{file}: no such result file (give a folder or result.json of jaxheli identify)")
    content = _read_json(file)
    if not isinstance(content, dict) or not isinstance(content.get("parameters"), dict):
        raise ValueError(f"{file}: field 'parameters': expected a {{name: value}} object of the 40 parameters")
    try:
        params = params_array(content["parameters"])
    except ValueError as err:
        raise ValueError(f"{file}: field 'parameters': {err}") from None
    for block in ("train", "validate"):
        value = content.get(block)
        if value is not None and not (isinstance(value, dict) and "pearson" in value and "tic" in value):
            raise ValueError(f"{file}: field '{block}': expected a metrics block with 'pearson' and 'tic'")
    npz = file.parent / "result.npz"
    history = np.zeros((1, 0))
    if npz.is_file():
        with np.load(npz) as arrays:
            if "history" in arrays:
                history = np.atleast_2d(np.asarray(arrays["history"], dtype=np.float64))
    return ResultSource(content.get("method", "?"), file.parent, content, params, history, _pngs(file.parent))


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not valid JSON ({err})") from None


def _findings(path: Path, data: Any) -> list[dict[str, Any]]:
    if not isinstance(data, list) or not all(isinstance(f, dict) for f in data):
        raise ValueError(f"{path}: field 'consistency': expected a list of findings (objects)")
    missing = [k for f in data for k in ("kind", "message") if k not in f]
    if missing:
        raise ValueError(f"{path}: field 'consistency': findings lack {sorted(set(missing))}")
    return data


def _pngs(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.png"))}

