"""The search box of the 40 parameters: one type for every engine (population, PEM, polish, uncertainty).

``unit = (theta - lower) / (upper - lower)`` maps each axis to ``[0, 1]`` (pinned axes, of zero width, read
0): the scale-free space population optimisers search and gradient solvers step in (``Lb``, width 100, and
``tf``, width 1, then weigh alike). Gradient solvers keep the box by simulating the clipped point
:meth:`Bounds.clip_unit` and adding a penalty on the distance outside (:meth:`Bounds.penalty`), so the slope stays 1 up to the bound (a
sigmoid map flattens there and freezes parameters that start or end near a bound).
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._types import Array, ArrayLike, Bool, Float, Params
from .model import LOWER, PARAM_NAMES, UPPER, WIDE_LOWER, WIDE_UPPER

Free = Bool[ArrayLike, "40"] | Sequence[str] | None
"""Free parameters: a mask over :data:`PARAM_NAMES`, a list of names, or ``None`` for every non-pinned one."""


PENALTY = 1e3
"""Weight of the distance outside the box (unit coordinates) in a least-squares solver's residuals."""


def _vector(value: ArrayLike) -> Float[Array, "dim"]:
    return jnp.asarray(value, dtype=float)


class Bounds(eqx.Module):
    """A box ``lower <= theta <= upper`` in physical units; ``lower == upper`` pins an axis.

    The arrays are pytree leaves, so one compiled engine serves every box of the same size.
    Default: the authors' box (:data:`jaxheli.LOWER`, :data:`jaxheli.UPPER`).
    """

    lower: Float[Array, "dim"] = eqx.field(converter=_vector, default_factory=LOWER.copy)
    upper: Float[Array, "dim"] = eqx.field(converter=_vector, default_factory=UPPER.copy)

    def __check_init__(self) -> None:
        if self.lower.ndim != 1 or self.lower.shape != self.upper.shape or self.lower.size == 0:
            raise ValueError(f"lower and upper must be equal non-empty 1-D shapes, got {self.lower.shape} "
                             f"and {self.upper.shape}")
        if not isinstance(self.lower, jax.core.Tracer):
            lo, hi = np.asarray(self.lower), np.asarray(self.upper)
            bad = np.flatnonzero(~(np.isfinite(lo) & np.isfinite(hi) & (lo <= hi)))
            if bad.size:
                raise ValueError(f"bounds must be finite with lower <= upper; bad axes {bad.tolist()}")

    @property
    def width(self) -> Float[Array, "dim"]:
        """``upper - lower`` (0 on pinned axes)."""
        return self.upper - self.lower

    @property
    def free(self) -> Bool[Array, "dim"]:
        """Axes a search may move (``upper > lower``)."""
        return self.upper > self.lower

    def to_unit(self, theta: Params) -> Float[Array, "*batch dim"]:
        """Physical -> unit coordinates (pinned axes map to 0)."""
        theta = jnp.asarray(theta)
        lower, width = (jnp.broadcast_to(v.astype(theta.dtype), theta.shape) for v in (self.lower, self.width))
        return jnp.where(width > 0, (theta - lower) / jnp.where(width > 0, width, 1.0), 0.0)

    def from_unit(self, unit: Float[ArrayLike, "*batch dim"]) -> Float[Array, "*batch dim"]:
        """Unit -> physical coordinates (pinned axes at their pinned value), unclipped."""
        unit = jnp.asarray(unit)
        lower, width = (jnp.broadcast_to(v.astype(unit.dtype), unit.shape) for v in (self.lower, self.width))
        return lower + width * unit

    def embed(
        self, base: Float[ArrayLike, "dim"], mask: Bool[np.ndarray, "dim"], unit: Float[ArrayLike, " n"]
    ) -> Float[Array, "dim"]:
        """Physical parameters: the axes of ``mask`` at the unit coordinates ``unit`` (in axis order, unclipped),
        the others at ``base`` (how a gradient solver's free coordinates become ``theta``)."""
        base = jnp.asarray(base)
        full = self.to_unit(base).at[np.flatnonzero(mask)].set(unit)
        return jnp.where(mask, self.from_unit(full), base)

    @staticmethod
    def clip_unit(unit: Float[ArrayLike, "*batch dim"]) -> Float[Array, "*batch dim"]:
        """The nearest point of the box, in unit coordinates; slope 1 on the closed box, 0 outside.

        (``jnp.clip`` has slope 1/2 on the bound itself, which would hold a parameter that lands exactly on
        a bound there.)
        """
        unit = jnp.asarray(unit)
        return jnp.where(unit < 0.0, 0.0, jnp.where(unit > 1.0, 1.0, unit))

    @staticmethod
    def penalty(unit: Float[ArrayLike, "*batch dim"]) -> Float[Array, "*batch dim"]:
        """``PENALTY (unit - clip(unit))``: residuals a least-squares solver appends so that its sum of squares
        rises steeply (but C1) past a bound; zero in the box."""
        unit = jnp.asarray(unit)
        return PENALTY * (unit - Bounds.clip_unit(unit))

    def midpoint(self) -> Float[np.ndarray, "dim"]:
        """The centre of the box (pinned parameters at their pinned value)."""
        return 0.5 * (np.asarray(self.lower, np.float64) + np.asarray(self.upper, np.float64))

    def uniform(self, key: ArrayLike, n: int) -> Float[np.ndarray, "n dim"]:
        """``n`` points drawn uniformly in the box from a PRNG ``key`` (physical units)."""
        lo, hi = np.asarray(self.lower, np.float64), np.asarray(self.upper, np.float64)
        return lo + (hi - lo) * np.asarray(jax.random.uniform(key, (n, lo.size)))

    def contains(self, theta: Float[ArrayLike, "*batch dim"]) -> Bool[np.ndarray, "*batch"]:
        """Whether each parameter vector lies in the closed box."""
        theta = np.asarray(theta, np.float64)
        return np.all((theta >= np.asarray(self.lower)) & (theta <= np.asarray(self.upper)), axis=-1)

    def free_mask(self, free: Free = None) -> Bool[np.ndarray, "dim"]:
        """Boolean mask of the free parameters: ``free`` (mask or names, default every axis of non-zero width);
        raises on unknown names or on a pinned (zero-width) one."""
        width = np.asarray(self.width)
        if free is None:
            mask = width > 0
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
                if mask.shape != width.shape:
                    raise ValueError(f"free: a mask needs shape {width.shape}, got {mask.shape}")
        pinned = [n for n, m, w in zip(PARAM_NAMES, mask, width) if m and w <= 0]
        if pinned:
            raise ValueError(f"free: {pinned} are pinned by the bounds (zero width) and cannot be fitted")
        if not mask.any():
            raise ValueError("free: no parameter is free")
        return mask

    def to_dict(self) -> dict[str, list[float]]:
        """``{"lower": [...], "upper": [...]}`` in :data:`PARAM_NAMES` order (JSON-ready)."""
        return {"lower": np.asarray(self.lower, np.float64).tolist(), "upper": np.asarray(self.upper, np.float64).tolist()}


def physical_box(box: Bounds) -> Bounds | None:
    """``box`` widened to the physical ranges (:data:`~jaxheli.model.WIDE_LOWER`, :data:`~jaxheli.model.WIDE_UPPER`;
    pinned axes freed, no bound narrowed), or ``None`` when it already holds them."""
    lower, upper = np.asarray(box.lower, np.float64), np.asarray(box.upper, np.float64)
    wide_lower, wide_upper = np.minimum(WIDE_LOWER, lower), np.maximum(WIDE_UPPER, upper)
    if np.array_equal(wide_lower, lower) and np.array_equal(wide_upper, upper):
        return None
    return Bounds(wide_lower, wide_upper)


BOXES: tuple[str, ...] = ("authors", "wide")
"""Named search boxes: ``"authors"`` (their ``config_iwo.m``, :data:`~jaxheli.model.LOWER` / ``UPPER``, five hover
terms pinned at 0) and ``"wide"`` (the authors' box widened to the physical ranges, pinned terms freed:
:func:`physical_box`)."""


def named_box(name: str) -> Bounds:
    """The search box called ``name`` (:data:`BOXES`)."""
    if name == "authors":
        return Bounds()
    if name == "wide":
        return physical_box(Bounds()) or Bounds()
    raise ValueError(f"box must be one of {BOXES}, got {name!r}")
