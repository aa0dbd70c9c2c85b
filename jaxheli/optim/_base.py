"""What the population optimisers share: unit-box coordinates, candidate batches, the ask/tell skeleton.

Every optimiser searches the unit box ``u in [0, 1]^dim``, one axis per parameter, mapped to physical
values by ``theta = lower + u (upper - lower)``. Axes with ``lower == upper`` are pinned: their unit
coordinate stays 0 and their value is exactly ``lower``. Costs that are NaN or +-inf are the worst
(+inf) wherever they come from, so a diverging candidate can neither become best nor crash a run.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Key

from .._types import Array, ArrayLike, Bool, Float, Int
from ..bounds import Bounds

CostFn = Callable[[Float[Array, "pop dim"]], Float[Array, "pop"]]
"""A batched cost: ``cost_fn(thetas[P, dim]) -> costs[P]``, lower is better, NaN/inf allowed."""

RawKey = Key[Array, ""] | Int[Array, "2"]
"""A PRNG key, typed (``jax.random.key``) or raw ``uint32[2]`` (``jax.random.PRNGKey``)."""


def raw_key(key: ArrayLike) -> Int[Array, "*batch 2"]:
    """The ``uint32`` data of a default (threefry) PRNG key, typed or raw (raw keys serialise with ``np.save``)."""
    key = jnp.asarray(key)
    if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        if str(jax.random.key_impl(key)) != "threefry2x32":
            raise ValueError(f"need a threefry2x32 key (jax.random.key(seed)), got {jax.random.key_impl(key)}")
        key = jax.random.key_data(key)
    if key.shape[-1:] != (2,) or key.dtype != jnp.uint32:
        raise ValueError(f"need threefry key data uint32[..., 2], got {key.dtype}{list(key.shape)}")
    return key


def _bound(value: ArrayLike) -> Float[Array, "dim"]:
    return jnp.asarray(value, dtype=float)


class Candidates(eqx.Module):
    """A fixed-size batch of candidates for one cost call.

    ``unit`` are unit-box coordinates, ``theta`` the physical values handed to the cost, ``real`` says
    which slots count (the others are padding in fixed-shape buffers; their cost is overwritten by inf).
    """

    unit: Float[Array, "batch dim"]
    theta: Float[Array, "batch dim"]
    real: Bool[Array, "batch"]


class AbstractPopulationOptimizer(eqx.Module):
    """Base of the box-bounded population optimisers (an immutable bag of hyperparameters).

    Subclasses provide ``init_ask / init_tell / ask / tell``; ``init`` and ``step`` pair them with a
    cost function. Splitting ask from tell lets :func:`jaxheli.optim.run.minimize_trials` score the
    candidates of many vmapped trials in one flat cost call.

    Attributes:
        lower, upper: ``[dim]`` search bounds in physical units; ``lower == upper`` pins an axis.
    """

    lower: Float[Array, "dim"] = eqx.field(converter=_bound)
    upper: Float[Array, "dim"] = eqx.field(converter=_bound)
    iterations: eqx.AbstractVar[int]

    def __check_init__(self) -> None:
        Bounds(self.lower, self.upper)
        if self.iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {self.iterations}")

    @property
    def dim(self) -> int:
        """Number of parameters (free and pinned)."""
        return self.lower.shape[0]

    @property
    def free(self) -> Bool[Array, "dim"]:
        """Axes the search may move (``upper > lower``)."""
        return self.upper > self.lower

    @property
    def bounds(self) -> Bounds:
        """The search box."""
        return Bounds(self.lower, self.upper)

    def to_theta(self, unit: Float[Array, "*batch dim"]) -> Float[Array, "*batch dim"]:
        """Unit-box coordinates -> physical values, clipped so rounding never leaves the box."""
        shape = unit.shape
        return jnp.clip(self.bounds.from_unit(unit), jnp.broadcast_to(self.lower, shape),
                        jnp.broadcast_to(self.upper, shape))

    def uniform(self, key: RawKey, n: int) -> Float[Array, "n dim"]:
        """``n`` uniform points of the unit box (pinned axes 0)."""
        unit = jax.random.uniform(key, (n, self.dim), dtype=self.lower.dtype)
        return jnp.where(jnp.broadcast_to(self.free, unit.shape), unit, 0.0)

    @abc.abstractmethod
    def init_ask(self, key: RawKey) -> Candidates:
        """The initial candidates drawn from ``key``."""

    @abc.abstractmethod
    def init_tell(self, key: RawKey, candidates: Candidates, costs: Float[Array, "batch"]) -> Any:
        """The initial state from the scored initial candidates (same ``key`` as :meth:`init_ask`)."""

    @abc.abstractmethod
    def ask(self, state: Any) -> Candidates:
        """The next generation's candidates (a pure function of ``state``)."""

    @abc.abstractmethod
    def tell(self, state: Any, candidates: Candidates, costs: Float[Array, "batch"]) -> Any:
        """The next state from the scored candidates of :meth:`ask`."""

    def init(self, key: RawKey, cost_fn: CostFn) -> Any:
        """Draw, score (:func:`score`) and rank the initial population."""
        key = raw_key(key)
        candidates = self.init_ask(key)
        return self.init_tell(key, candidates, score(cost_fn, candidates, self.score_batch))

    @property
    def score_batch(self) -> int | None:
        """Candidates per ``cost_fn`` call in :func:`score` (``None``: the whole buffer in one call)."""
        return None

    def step(self, state: Any, cost_fn: CostFn) -> Any:
        """One generation: ask, score the real candidates (:func:`score`), tell."""
        candidates = self.ask(state)
        return self.tell(state, candidates, score(cost_fn, candidates, self.score_batch))


def score(cost_fn: CostFn, candidates: Candidates, batch: int | None) -> Float[Array, "n"]:
    """Costs of ``candidates``: padding slots +inf and never scored.

    With ``batch``, the real candidates are moved to the front and scored ``batch`` at a time in a
    ``lax.map``; a batch holding no real candidate is skipped (``lax.cond``), so a generation costs what its
    real candidates cost, not its fixed buffer (IWO scores about 120 real seeds in a buffer of 280). Each
    candidate's cost is that of ``cost_fn`` on it alone (cast to the candidates' dtype); ``batch=None`` scores the
    whole buffer in one call.
    """
    real, thetas = candidates.real, candidates.theta
    n, dim = thetas.shape
    if batch is None or batch >= n:
        return sanitise(cost_fn(thetas), real)
    chunks = -(-n // batch)
    order = jnp.argsort(~real, stable=True)
    padded = jnp.concatenate([thetas[order], jnp.broadcast_to(thetas[:1], (chunks * batch - n, dim))])
    n_real = jnp.sum(real)

    def scored(block: Float[Array, "batch dim"]) -> Float[Array, "batch"]:
        return jnp.asarray(cost_fn(block), block.dtype)

    def skipped(block: Float[Array, "batch dim"]) -> Float[Array, "batch"]:
        return jnp.full(batch, jnp.inf, block.dtype)

    def one(args: tuple[Int[Array, ""], Float[Array, "batch dim"]]) -> Float[Array, "batch"]:
        index, block = args
        return jax.lax.cond(index * batch < n_real, scored, skipped, block)

    costs = jax.lax.map(one, (jnp.arange(chunks), padded.reshape(chunks, batch, dim))).reshape(-1)[:n]
    return sanitise(jnp.zeros(n, thetas.dtype).at[order].set(costs), real)


def sanitise(costs: Float[Array, "batch"], real: Bool[Array, "batch"]) -> Float[Array, "batch"]:
    """Costs with non-finite values and padding slots replaced by +inf (the worst)."""
    costs = jnp.asarray(costs)
    if costs.shape != real.shape:
        raise ValueError(f"cost_fn returned shape {costs.shape}, expected {real.shape}")
    return jnp.where(real & jnp.isfinite(costs), costs, jnp.inf)


def rank(costs: Float[Array, "n"], alive: Bool[Array, "n"]) -> Int[Array, "n"]:
    """Indices sorting by cost, real entries before padding at equal cost; stable (earlier first)."""
    return jnp.lexsort((~alive, costs))


def update_best(
    best_theta: Float[Array, "dim"], best_cost: Float[Array, ""], theta: Float[Array, "dim"], cost: Float[Array, ""]
) -> tuple[Float[Array, "dim"], Float[Array, ""]]:
    """Keep the better of the incumbent and a challenger (strictly better replaces; inf never does)."""
    better = cost < best_cost
    return jnp.where(better, theta, best_theta), jnp.where(better, cost, best_cost)
