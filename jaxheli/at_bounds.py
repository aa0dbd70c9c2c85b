"""Identified parameters that sit on a bound of the search box.

A parameter on its bound is not an estimate: the box, not the flight, decided its value, and the optimiser's
intervals and standard errors say nothing of where the flight would put it (trials that all stop on the bound give
a zero-width interval). Pinned axes (``lower == upper``) are left out: the box fixes them on purpose.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from ._types import Float
from .model import LOWER, PARAM_NAMES, UPPER

TOLERANCE = 1e-3
"""Distance to a bound, as a share of the axis's width (0.1 %), within which a parameter counts as on it."""


@dataclasses.dataclass(frozen=True)
class AtBound:
    """A parameter on a bound: its ``name``, ``value``, which ``side`` and the ``bound``'s value (its units)."""

    name: str
    value: float
    side: Literal["lower", "upper"]
    bound: float

    def to_json(self) -> dict[str, object]:
        """JSON-ready values."""
        return dataclasses.asdict(self)


def at_bounds(
    theta: Float[np.ndarray, "40"],
    lower: Float[np.ndarray, "40"] = LOWER,
    upper: Float[np.ndarray, "40"] = UPPER,
    tolerance: float = TOLERANCE,
) -> tuple[AtBound, ...]:
    """The free parameters of ``theta`` within ``tolerance`` of the box's width from ``lower`` or ``upper``
    (default: the authors' box), in :data:`jaxheli.model.PARAM_NAMES` order."""
    theta, lower, upper = (np.asarray(v, dtype=np.float64) for v in (theta, lower, upper))
    near = tolerance * (upper - lower)
    found = []
    for name, value, lo, hi, margin in zip(PARAM_NAMES, theta, lower, upper, near):
        if hi > lo and value <= lo + margin:
            found.append(AtBound(name, float(value), "lower", float(lo)))
        elif hi > lo and value >= hi - margin:
            found.append(AtBound(name, float(value), "upper", float(hi)))
    return tuple(found)
