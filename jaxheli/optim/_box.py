"""The authors' search box: free-parameter masks and the unit ``[0, 1]`` coordinates of each axis.

``unit = (theta - LOWER) / (UPPER - LOWER)`` (pinned axes, of zero width, read 0): the scale-free space
of population optimisers, and the space gradient solvers step in (``Lb``, width 100, and ``tf``, width 1,
then weigh alike). Solvers keep bounds by simulating the clipped point :func:`clip_unit` and adding a
penalty on the distance outside, so the slope stays 1 up to the bound (a sigmoid map flattens there and
freezes parameters that start or end near a bound).
"""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from .._types import Array, ArrayLike, Bool, Float, Params
from ..model import LOWER, N_PARAMS, PARAM_NAMES, PINNED, UPPER

Free = Bool[ArrayLike, "40"] | Sequence[str] | None
"""Free parameters: a mask over :data:`PARAM_NAMES`, a list of names, or ``None`` for every non-pinned one."""

_WIDTH = UPPER - LOWER


def free_mask(free: Free = None) -> Bool[np.ndarray, "40"]:
    """Boolean mask of the free parameters; raises on unknown names or on a pinned (zero-width) one."""
    if free is None:
        mask = np.array([n not in PINNED for n in PARAM_NAMES])
    elif isinstance(free, (str, bytes)):
        raise ValueError(f"free must be a mask or a list of names, got the string {free!r}")
    else:
        items = list(free)
        if items and all(isinstance(f, str) for f in items):
            unknown = sorted(set(items) - set(PARAM_NAMES))
            if unknown:
                raise ValueError(f"free: unknown parameter names {unknown}")
            mask = np.array([n in items for n in PARAM_NAMES])
        else:
            mask = np.asarray(items, dtype=bool)
            if mask.shape != (N_PARAMS,):
                raise ValueError(f"free: a mask needs shape (40,), got {mask.shape}")
    pinned = [n for n, m, w in zip(PARAM_NAMES, mask, _WIDTH) if m and w <= 0]
    if pinned:
        raise ValueError(f"free: {pinned} are pinned by the bounds (zero width) and cannot be fitted")
    if not mask.any():
        raise ValueError("free: no parameter is free")
    return mask


def to_unit(theta: Params) -> Float[Array, "*batch 40"]:
    """Physical -> unit coordinates (pinned axes map to 0)."""
    theta = jnp.asarray(theta)
    lower, width = (jnp.broadcast_to(jnp.asarray(v, theta.dtype), theta.shape) for v in (LOWER, _WIDTH))
    return jnp.where(width > 0, (theta - lower) / jnp.where(width > 0, width, 1.0), 0.0)


def from_unit(unit: Float[ArrayLike, "*batch 40"]) -> Float[Array, "*batch 40"]:
    """Unit -> physical coordinates (pinned axes at their pinned value)."""
    unit = jnp.asarray(unit)
    lower, width = (jnp.broadcast_to(jnp.asarray(v, unit.dtype), unit.shape) for v in (LOWER, _WIDTH))
    return lower + width * unit


def clip_unit(unit: Float[ArrayLike, "*batch 40"]) -> Float[Array, "*batch 40"]:
    """The nearest point of the box, in unit coordinates; slope 1 on the closed box, 0 outside.

    (``jnp.clip`` has slope 1/2 on the bound itself, which would hold a parameter that lands exactly on
    a bound there.)
    """
    unit = jnp.asarray(unit)
    return jnp.where(unit < 0.0, 0.0, jnp.where(unit > 1.0, 1.0, unit))


def midpoint() -> Float[np.ndarray, "40"]:
    """The centre of the box (pinned parameters at their pinned value)."""
    return 0.5 * (LOWER + UPPER)
