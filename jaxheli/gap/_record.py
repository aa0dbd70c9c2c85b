"""The machinery of the diagnosis's frozen records (:mod:`~jaxheli.gap.records`,
:mod:`~jaxheli.gap.localisation_record`): each field written to JSON and read back by its annotated type."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from functools import partial
from typing import Any

import numpy as np

from .._types import Float
from ..effects.registry import json_number
from ..model import PARAM_NAMES


Theta = Float[np.ndarray, "40"]
"""Base parameters in the order of :data:`~jaxheli.model.PARAM_NAMES` (JSON: an object by name)."""


def _named(theta: Theta) -> dict[str, float]:
    return dict(zip(PARAM_NAMES, map(float, np.asarray(theta))))


def _theta(named: Mapping[str, float | None]) -> Theta:
    return np.array([json_number(named[n]) for n in PARAM_NAMES])


def _same(value: Any) -> Any:
    return value


def _floats(named: Mapping[str, float | None]) -> dict[str, float]:
    return {k: json_number(v) for k, v in named.items()}


def _maybe(read: Any, data: Any) -> Any:
    return None if data is None else read(data)


_WRITE = {"Mapping[str, float]": dict, "Theta": _named, "tuple[str, ...]": list,
          "tuple[Mapping[str, Any], ...]": list, "tuple[float, ...]": list, "tuple[float, float]": list,
          "tuple[float, float] | None": partial(_maybe, list),
          "tuple[Mapping[str, float], ...]": lambda named: list(map(dict, named))}
"""How a record field of each annotated type is written to JSON (as it is where not named here)."""

_READ = {"float": json_number, "int": int, "bool": bool, "str": str, "Mapping[str, float]": _floats,
         "Theta": _theta, "tuple[str, ...]": tuple, "tuple[Mapping[str, Any], ...]": tuple,
         "float | None": _same, "str | None": _same, "tuple[float, ...]": tuple, "tuple[float, float]": tuple,
         "tuple[float, float] | None": partial(_maybe, tuple),
         "tuple[Mapping[str, float], ...]": lambda named: tuple(map(_floats, named))}
"""How a record field of each annotated type is read back from JSON (``float | None``: ``None`` kept, an undefined
quantity)."""


def _write(record: Any, *omit: str) -> dict[str, Any]:
    """The fields of a frozen record but ``omit``, by name, as JSON values (:data:`_WRITE`), in field order."""
    return {f.name: _WRITE.get(f.type, _same)(getattr(record, f.name)) for f in dataclasses.fields(record)
            if f.name not in omit}


def _json(record: Any) -> dict[str, Any] | None:
    return None if record is None else record.to_json()


def _read(cls: type, data: Mapping[str, Any], **given: Any) -> Any:
    """The record ``cls`` of JSON ``data``: the fields ``given``, the others read by their type (:data:`_READ`)."""
    return cls(**{f.name: given[f.name] if f.name in given else _READ[f.type](data[f.name])
                  for f in dataclasses.fields(cls)})


class _Flat:
    """A record whose every field is written and read by its annotated type (:func:`_write`, :func:`_read`;
    other keys of the JSON ignored)."""

    def to_json(self) -> dict[str, Any]:
        """The fields by name, in field order."""
        return _write(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Any:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data)
