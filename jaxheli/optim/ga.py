"""A real-coded genetic algorithm in the unit box, the paper's comparison method (GA column of its Table 1;
the paper gives no GA settings, these are textbook defaults).

One generation: ``population - elite`` children, each from two parents picked by tournament, blended by
BLX-alpha crossover (each gene uniform on the parents' interval widened by ``blend`` of its length on
both sides) with probability ``crossover_rate``, then Gaussian mutation of each free gene with
probability ``mutation_rate`` and a spread decaying geometrically from ``sigma_initial`` to
``sigma_final`` (fractions of each bound width), clipped to the box. The ``elite`` best parents survive
unchanged; the children replace the rest (generational replacement with elitism).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import Array, ArrayLike, Float, Int
from ._base import AbstractPopulationOptimizer, Candidates, RawKey, rank, sanitise, update_best


class GAState(eqx.Module):
    """GA state after ``iteration`` generations.

    Attributes:
        population: ``[population, dim]`` unit-box coordinates, sorted best first.
        costs: ``[population]`` costs (+inf for diverged candidates).
        key: raw PRNG key for the next generation.
        iteration: generations done.
        best_theta: ``[dim]`` best parameters found, physical units.
        best_cost: its cost (+inf until a finite cost is seen).
        n_evaluations: candidates scored so far.
    """

    population: Float[Array, "pop dim"]
    costs: Float[Array, "pop"]
    key: Int[Array, "2"]
    iteration: Int[Array, ""]
    best_theta: Float[Array, "dim"]
    best_cost: Float[Array, ""]
    n_evaluations: Int[Array, ""]


class GA(AbstractPopulationOptimizer):
    """Real-coded GA with tournament selection, BLX-alpha crossover, decaying Gaussian mutation, elitism.

    Attributes:
        lower, upper: ``[dim]`` bounds, physical units (``lower == upper`` pins an axis).
        population: individuals per generation.
        elite: best individuals copied unchanged into the next generation.
        tournament: contestants per parent selection.
        crossover_rate: probability a child is a blend (otherwise a copy of its first parent).
        blend: BLX ``alpha``, widening of the parents' interval on each side.
        mutation_rate: probability each free gene of a child is mutated.
        sigma_initial, sigma_final: mutation standard deviation at the first and last generation, as a
            fraction of each bound width.
        iterations: generations of the mutation schedule.
    """

    population: int = eqx.field(default=40, static=True)
    elite: int = eqx.field(default=2, static=True)
    tournament: int = eqx.field(default=3, static=True)
    crossover_rate: float = eqx.field(default=0.9, static=True)
    blend: float = eqx.field(default=0.5, static=True)
    mutation_rate: float = eqx.field(default=0.1, static=True)
    sigma_initial: float = eqx.field(default=0.1, static=True)
    sigma_final: float = eqx.field(default=0.001, static=True)
    iterations: int = eqx.field(default=1000, static=True)

    def __check_init__(self) -> None:
        if not 0 <= self.elite < self.population:
            raise ValueError(f"need 0 <= elite < population, got {self.elite}, {self.population}")
        if self.tournament < 1:
            raise ValueError(f"tournament must be >= 1, got {self.tournament}")
        if not (0 <= self.crossover_rate <= 1 and 0 <= self.mutation_rate <= 1 and self.blend >= 0):
            raise ValueError("need crossover_rate and mutation_rate in [0, 1] and blend >= 0")
        if not self.sigma_initial >= self.sigma_final > 0:
            raise ValueError("need sigma_initial >= sigma_final > 0")

    def sigma(self, generation: Int[ArrayLike, "*batch"]) -> Float[Array, "*batch"]:
        """Mutation spread of ``generation`` (1 .. iterations): geometric from initial to final."""
        done = jnp.clip((jnp.asarray(generation) - 1) / max(self.iterations - 1, 1), 0.0, 1.0)
        return self.sigma_initial * (self.sigma_final / self.sigma_initial) ** done

    def init_ask(self, key: RawKey) -> Candidates:
        unit = self.uniform(jax.random.split(key)[0], self.population)
        return Candidates(unit, self.to_theta(unit), jnp.ones(self.population, bool))

    def init_tell(self, key: RawKey, candidates: Candidates, costs: Float[Array, "pop"]) -> GAState:
        return self._ranked(
            candidates.unit,
            sanitise(costs, candidates.real),
            key=jax.random.split(key)[1],
            iteration=jnp.asarray(0, dtype=int),
            best=(self.to_theta(candidates.unit[0]), jnp.asarray(jnp.inf, candidates.unit.dtype)),
            n_evaluations=jnp.asarray(self.population, dtype=int),
        )

    def ask(self, state: GAState) -> Candidates:
        """``population - elite`` children (two random draws per generation: one uniform block, one normal)."""
        n, t, d = self.population - self.elite, self.tournament, self.dim
        k_uniform, k_normal = jax.random.split(jax.random.split(state.key)[0])
        u = jax.random.uniform(k_uniform, (n, 2 * t + 1 + 2 * d), state.population.dtype)
        picks, cross, blend, mutate = jnp.split(u, [2 * t, 2 * t + 1, 2 * t + 1 + d], axis=1)
        contestants = jnp.minimum(picks * self.population, self.population - 1).astype(int).reshape(n, 2, t)
        winners = jnp.take_along_axis(contestants, jnp.argmin(state.costs[contestants], axis=2)[..., None], axis=2)
        parents = state.population[winners[..., 0]]
        first, second = parents[:, 0], parents[:, 1]
        weight = (1.0 + 2.0 * self.blend) * blend - self.blend
        child = jnp.where(cross < self.crossover_rate, first + weight * (second - first), first)
        noise = jax.random.normal(k_normal, child.shape, child.dtype) * self.sigma(state.iteration + 1)
        mutated = (mutate < self.mutation_rate) & self.free[None, :]
        unit = jnp.clip(jnp.where(mutated, child + noise, child), 0.0, 1.0)
        return Candidates(unit, self.to_theta(unit), jnp.ones(n, bool))

    def tell(self, state: GAState, candidates: Candidates, costs: Float[Array, "children"]) -> GAState:
        """The elite of the parents plus every child, ranked."""
        return self._ranked(
            jnp.concatenate([state.population[: self.elite], candidates.unit]),
            jnp.concatenate([state.costs[: self.elite], sanitise(costs, candidates.real)]),
            key=jax.random.split(state.key)[1],
            iteration=state.iteration + 1,
            best=(state.best_theta, state.best_cost),
            n_evaluations=state.n_evaluations + candidates.real.shape[0],
        )

    def _ranked(
        self,
        unit: Float[Array, "pop dim"],
        costs: Float[Array, "pop"],
        *,
        key: Int[Array, "2"],
        iteration: Int[Array, ""],
        best: tuple[Float[Array, "dim"], Float[Array, ""]],
        n_evaluations: Int[Array, ""],
    ) -> GAState:
        order = rank(costs, jnp.ones(costs.shape, bool))
        best_theta, best_cost = update_best(*best, self.to_theta(unit[order[0]]), costs[order[0]])
        return GAState(unit[order], costs[order], key, iteration, best_theta, best_cost, n_evaluations)
