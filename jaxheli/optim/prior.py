"""A Gaussian prior on the 40 parameters, as extra least-squares residuals of the local fits.

A prior model ``m`` (any model :func:`jaxheli.evaluate.resolve_params` reads: a ``result.json``, ``table2``) with a
standard deviation of ``pct`` % adds one residual per free parameter to PEM's and the polish's residuals
(:func:`jaxheli.optim.pem.fit`, the one least-squares engine both use):

    r_prior_i = (theta_i - m_i) / sd_i,    sd_i = pct / 100 * max(|m_i|, floor_i)

so its sum of squares is ``-2 log`` of the prior density up to a constant, on the scale of the normalised output
errors (each of which has unit variance where the model fits to the noise). The floor keeps a parameter whose prior
value is 0 (or near it) from being pinned there: ``floor_i`` is :data:`FLOOR_FRACTION` of the parameter's physical
range (:data:`~jaxheli.model.WIDE_UPPER` - :data:`~jaxheli.model.WIDE_LOWER`), in the parameter's own units (e.g.
0.04 1/s for ``Xu``, 0.2 for ``Mcol``), because the 40 parameters span six orders of magnitude and no single number
suits them all.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._types import Array, ArrayLike, Float
from ..model import N_PARAMS, PARAM_NAMES, WIDE_LOWER, WIDE_UPPER

FLOOR_FRACTION = 0.01
"""Share of each parameter's physical range below which ``|prior|`` does not shrink the prior's standard deviation
(1 %: a 0-valued prior with ``pct`` = 50 still lets the parameter move by 0.5 % of its range per unit residual)."""


def prior_floor() -> Float[np.ndarray, "40"]:
    """``FLOOR_FRACTION * (WIDE_UPPER - WIDE_LOWER)``: the default floor of each parameter, its units."""
    return FLOOR_FRACTION * (WIDE_UPPER - WIDE_LOWER)


class Prior(eqx.Module):
    """Independent Gaussian prior: ``mean[40]`` and standard deviation ``sd[40]`` (physical units, > 0).

    Arrays are pytree leaves, so every prior of the same shape shares one compiled solver.
    """

    mean: Float[Array, "40"] = eqx.field(converter=lambda v: jnp.asarray(v, dtype=float))
    sd: Float[Array, "40"] = eqx.field(converter=lambda v: jnp.asarray(v, dtype=float))

    def __check_init__(self) -> None:
        if self.mean.shape != (N_PARAMS,) or self.sd.shape != (N_PARAMS,):
            raise ValueError(f"Prior: mean and sd need shape ({N_PARAMS},), got {self.mean.shape}, {self.sd.shape}")
        if not np.all(np.isfinite(np.asarray(self.mean))) or not np.all(np.asarray(self.sd) > 0):
            raise ValueError("Prior: mean must be finite and sd positive")

    @classmethod
    def from_percent(
        cls, mean: Float[ArrayLike, "40"], pct: float, floor: Float[ArrayLike, "40"] | float | None = None
    ) -> Prior:
        """The prior ``sd = pct / 100 * max(|mean|, floor)`` (``floor`` default: :func:`prior_floor`)."""
        if not pct > 0:
            raise ValueError(f"Prior: the standard deviation in percent must be > 0, got {pct}")
        mean = np.asarray(mean, dtype=np.float64)
        floor = prior_floor() if floor is None else np.broadcast_to(np.asarray(floor, np.float64), mean.shape)
        return cls(mean, pct / 100.0 * np.maximum(np.abs(mean), floor))

    def residuals(self, theta: Float[ArrayLike, "40"], index: np.ndarray | None = None) -> Float[Array, " n"]:
        """``(theta - mean) / sd`` over the axes ``index`` (default all 40)."""
        theta = jnp.asarray(theta)
        r = (theta - self.mean.astype(theta.dtype)) / self.sd.astype(theta.dtype)
        return r if index is None else r[index]

    def to_dict(self) -> dict[str, dict[str, float]]:
        """``{"mean": {name: value}, "sd": {name: value}}`` (JSON-ready)."""
        return {"mean": dict(zip(PARAM_NAMES, np.asarray(self.mean, np.float64).tolist())),
                "sd": dict(zip(PARAM_NAMES, np.asarray(self.sd, np.float64).tolist()))}
