"""Invasive Weed Optimization (Mehrabian & Lucas 2006), the paper's identification method (Eq. 8).

One generation: every plant sows seeds, from ``min_seeds`` (worst plant) to ``max_seeds`` (best plant),
linear in its cost; seeds fall normally around the parent with a spread that shrinks from
``sigma_initial`` to ``sigma_final``; parents and seeds compete together and the best
``max_population`` survive (while fewer exist, all survive).

Fixed shapes for jit: the population holds ``max_population`` slots with an ``alive`` mask, the seed
buffer ``max_population * max_seeds`` slots with a ``real`` mask, and the whole buffer is scored by one
cost call per generation (padding slots hold in-bounds points; their cost is overwritten by +inf).

**Sigma units.** The authors' MATLAB (Yarpiz ``iwo.m`` with ``config_iwo.m``) adds ``sigma * randn`` to
the raw parameter vector, so their 0.9 -> 0.001 is absolute and the same for all 40 parameters, whose
bound widths span 0.01 (``Nv``) to 260 (``Zb``): early seeds of ``Mu`` (width 0.2) are clipped onto its
bounds almost every time, while ``Lb`` (width 100) barely moves. We default to ``sigma_units="unit"``:
sigma is a fraction of each parameter's bound width (dispersal in the unit box), so 0.9 -> 0.001 means
"nearly the whole box" -> "a thousandth of it" on every axis, the scale-free reading of Mehrabian &
Lucas. ``sigma_units="absolute"`` reproduces the authors' code.

**Modulation.** With the paper's ``n = 0.5`` the spread is still ``0.28`` box widths after 90 % of the
generations (a square-root schedule), so the search stays nearly global until the very end; Mehrabian
& Lucas recommend ``n = 3``, which narrows to a tenth of the box by mid-run. On a synthetic 35-parameter
hover identification (1000 generations, one trial) ``n = 3`` reached a cost 400 times lower than ``n = 0.5``
(unit or absolute sigma alike). The defaults stay the paper's.
"""

from __future__ import annotations

from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import Array, ArrayLike, Bool, Float, Int
from ._base import AbstractPopulationOptimizer, Candidates, RawKey, rank, sanitise, update_best


class IWOState(eqx.Module):
    """IWO state after ``iteration`` generations.

    Attributes:
        population: ``[max_population, dim]`` unit-box coordinates, sorted best first.
        costs: ``[max_population]`` costs; +inf for dead slots and diverged plants.
        alive: ``[max_population]`` which slots hold plants.
        key: raw PRNG key for the next generation.
        iteration: generations done.
        best_theta: ``[dim]`` best parameters found, physical units.
        best_cost: its cost (+inf until a finite cost is seen).
        n_evaluations: real candidates scored so far (padding slots not counted).
    """

    population: Float[Array, "max_pop dim"]
    costs: Float[Array, "max_pop"]
    alive: Bool[Array, "max_pop"]
    key: Int[Array, "2"]
    iteration: Int[Array, ""]
    best_theta: Float[Array, "dim"]
    best_cost: Float[Array, ""]
    n_evaluations: Int[Array, ""]


class IWO(AbstractPopulationOptimizer):
    """Invasive Weed Optimization; defaults are the paper's settings (1000 iterations; 5000 in later code).

    Attributes:
        lower, upper: ``[dim]`` bounds, physical units (``lower == upper`` pins an axis).
        initial_population: plants sown uniformly at the start.
        max_population: plants kept by competitive exclusion.
        min_seeds, max_seeds: seeds of the worst and of the best plant.
        modulation: the non-linear modulation index ``n`` of the sigma schedule.
        sigma_initial, sigma_final: dispersal standard deviation at the first and last generation, in
            ``sigma_units``.
        iterations: ``iter_max`` of the sigma schedule.
        sigma_units: ``"unit"`` (fraction of each bound width, default) or ``"absolute"`` (physical
            units of every parameter, as the authors' MATLAB); see the module docstring.
    """

    initial_population: int = eqx.field(default=20, static=True)
    max_population: int = eqx.field(default=40, static=True)
    min_seeds: int = eqx.field(default=2, static=True)
    max_seeds: int = eqx.field(default=7, static=True)
    modulation: float = eqx.field(default=0.5, static=True)
    sigma_initial: float = eqx.field(default=0.9, static=True)
    sigma_final: float = eqx.field(default=0.001, static=True)
    iterations: int = eqx.field(default=1000, static=True)
    sigma_units: Literal["unit", "absolute"] = eqx.field(default="unit", static=True)

    def __check_init__(self) -> None:
        if not 1 <= self.initial_population <= self.max_population:
            raise ValueError(f"need 1 <= initial_population <= max_population, got {self.initial_population}, "
                             f"{self.max_population}")
        if not (0 <= self.min_seeds <= self.max_seeds and self.max_seeds >= 1):
            raise ValueError(f"need 0 <= min_seeds <= max_seeds and max_seeds >= 1; got {self.min_seeds}, "
                             f"{self.max_seeds}")
        if not (self.sigma_initial >= self.sigma_final >= 0 and self.modulation > 0):
            raise ValueError("need sigma_initial >= sigma_final >= 0 and modulation > 0")
        if self.sigma_units not in ("unit", "absolute"):
            raise ValueError(f"sigma_units must be 'unit' or 'absolute', got {self.sigma_units!r}")

    def sigma(self, generation: Int[ArrayLike, "*batch"]) -> Float[Array, "*batch"]:
        """Dispersal of ``generation`` (1 .. iterations), paper Eq. 8 / Mehrabian & Lucas:

        ``((iter_max - iter) / iter_max)^n (sigma_initial - sigma_final) + sigma_final``; generation 1 is
        close to ``sigma_initial``, generation ``iter_max`` (and beyond) is ``sigma_final``, as in the
        authors' MATLAB. (The paper's printed Eq. 8 drops the power ``n`` on the denominator; this is the
        original normalisation, ``DESIGN.md`` section 2.)
        """
        left = jnp.clip((self.iterations - jnp.asarray(generation)) / self.iterations, 0.0, 1.0)
        return left**self.modulation * (self.sigma_initial - self.sigma_final) + self.sigma_final

    @property
    def score_batch(self) -> int:
        """Seeds scored per cost call: ``max_population`` per local device (of the ``max_population * max_seeds``
        buffer only the batches holding real seeds are scored, :func:`~jaxheli.optim._base.score`; a batch is
        spread over the devices, :func:`~jaxheli.sim.shard.map_population`)."""
        return self.max_population * jax.local_device_count()

    def init_ask(self, key: RawKey) -> Candidates:
        unit = self.uniform(jax.random.split(key)[0], self.initial_population)
        return Candidates(unit, self.to_theta(unit), jnp.ones(self.initial_population, bool))

    def init_tell(self, key: RawKey, candidates: Candidates, costs: Float[Array, "n0"]) -> IWOState:
        pad = self.max_population - self.initial_population
        unit = jnp.concatenate([candidates.unit, jnp.zeros((pad, self.dim), candidates.unit.dtype)])
        costs = jnp.concatenate([sanitise(costs, candidates.real), jnp.full(pad, jnp.inf, candidates.unit.dtype)])
        alive = jnp.arange(self.max_population) < self.initial_population
        order = rank(costs, alive)
        return IWOState(
            population=unit[order],
            costs=costs[order],
            alive=alive[order],
            key=jax.random.split(key)[1],
            iteration=jnp.asarray(0, dtype=int),
            best_theta=self.to_theta(unit[order[0]]),
            best_cost=costs[order[0]],
            n_evaluations=jnp.asarray(self.initial_population, dtype=int),
        )

    def ask(self, state: IWOState) -> Candidates:
        """Seeds of every plant in a ``[max_population * max_seeds, dim]`` buffer, plant-major."""
        m, s = self.max_population, self.max_seeds
        counts = _seed_counts(state.costs, state.alive, self.min_seeds, self.max_seeds)
        parent = jnp.repeat(jnp.arange(m), s)
        real = jnp.tile(jnp.arange(s), m) < counts[parent]
        width = self.upper - self.lower
        per_axis = jnp.where(self.free, 1.0 / jnp.where(self.free, width, 1.0), 0.0)
        scale = self.sigma(state.iteration + 1) * (per_axis if self.sigma_units == "absolute" else self.free)
        noise = jax.random.normal(jax.random.split(state.key)[0], (m * s, self.dim), state.population.dtype)
        unit = jnp.clip(state.population[parent] + noise * scale[None, :], 0.0, 1.0)
        return Candidates(unit, self.to_theta(unit), real)

    def tell(self, state: IWOState, candidates: Candidates, costs: Float[Array, "buffer"]) -> IWOState:
        """Competitive exclusion: parents and seeds ranked together, the best ``max_population`` stay."""
        unit = jnp.concatenate([state.population, candidates.unit])
        costs = jnp.concatenate([state.costs, sanitise(costs, candidates.real)])
        alive = jnp.concatenate([state.alive, candidates.real])
        keep = rank(costs, alive)[: self.max_population]
        best_theta, best_cost = update_best(state.best_theta, state.best_cost, self.to_theta(unit[keep[0]]),
                                            costs[keep[0]])
        return IWOState(
            population=unit[keep],
            costs=costs[keep],
            alive=alive[keep],
            key=jax.random.split(state.key)[1],
            iteration=state.iteration + 1,
            best_theta=best_theta,
            best_cost=best_cost,
            n_evaluations=state.n_evaluations + jnp.sum(candidates.real),
        )


_COUNT_SLACK = 1e-9
"""Added to the seed count before ``floor`` (see :func:`_seed_counts`)."""


def _seed_counts(
    costs: Float[Array, "n"], alive: Bool[Array, "n"], min_seeds: int, max_seeds: int
) -> Int[Array, "n"]:
    """Seeds per plant, ``floor(min + (max - min) (worst - cost) / (worst - best))`` over finite costs.

    The best plant gets ``max_seeds``, the worst ``min_seeds`` (all ``max_seeds`` when every finite cost
    is equal); plants with a non-finite cost get ``min_seeds``, dead slots 0. A count within
    :data:`_COUNT_SLACK` of the next integer is rounded up, so the last digit of a cost cannot change it (beside a
    diverging plant's huge cost every other plant's share is ``max_seeds - O(1e-16)``).
    """
    finite = alive & jnp.isfinite(costs)
    best = jnp.min(jnp.where(finite, costs, jnp.inf))
    worst = jnp.max(jnp.where(finite, costs, -jnp.inf))
    spread = worst - best
    ratio = jnp.where(spread > 0, (worst - costs) / jnp.where(spread > 0, spread, 1.0), 1.0)
    ratio = jnp.where(finite, jnp.clip(ratio, 0.0, 1.0), 0.0)
    counts = jnp.floor(min_seeds + (max_seeds - min_seeds) * ratio + _COUNT_SLACK).astype(int)
    return jnp.where(alive, counts, 0)
