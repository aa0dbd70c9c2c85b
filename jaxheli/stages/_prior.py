"""The prior model the least-squares stages (PEM, the polish) share: a model and its spread in percent."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Union

import numpy as np

from .._types import Float
from ..evaluate import resolve_params
from ..optim.prior import Prior

PRIOR_SD = 50.0
"""Default standard deviation of a prior model, percent of each value (floored, :mod:`jaxheli.optim.prior`): a weak
prior, which a record that determines a parameter overrules; a tighter one is a choice to state (``prior_sd``)."""

PriorModel = Union[str, Path, dict, Float[np.ndarray, "40"]]
"""Anything :func:`jaxheli.evaluate.resolve_params` reads: a result.json, a name such as ``"table2"``, 40 values."""


def belief(model: PriorModel | None, sd: float | None) -> Prior | None:
    """The Gaussian prior of ``model`` with ``sd`` percent of each value (default :data:`PRIOR_SD`; ``None``
    without a model, where ``sd`` is refused)."""
    if model is None:
        if sd is not None:
            raise ValueError(f"prior_sd={sd!r} needs a prior model (prior)")
        return None
    return Prior.from_percent(resolve_params(model), PRIOR_SD if sd is None else sd)


def prior_settings(model: PriorModel | None, sd: float | None) -> dict[str, Any]:
    """How ``IdentificationResult.settings`` records the prior: its name or file, else its 40 values, and its
    spread (both ``None`` without a model)."""
    if model is None:
        return {"prior": None, "prior_sd": None}
    described = str(model) if isinstance(model, (str, Path)) else resolve_params(model).tolist()
    return {"prior": described, "prior_sd": float(PRIOR_SD if sd is None else sd)}
