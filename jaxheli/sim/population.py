"""The search cost (the paper's, or the output error) for a whole population of candidates in one jitted call."""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax.numpy as jnp

from .._types import Array, Float, Population
from ..cost import SearchCost, paper_cost, search_cost
from ..data.flight import FlightData
from .pearson_sums import blocked_cost
from .shard import map_population
from .simulate import Simulator, make_simulator


@eqx.filter_jit
def simulator_cost(sim: Simulator, thetas: Array, target: Array, *, shard: bool | None = None) -> Array:
    """Paper cost of ``thetas[P, 40]`` under a prepared simulator against ``target[N, k]``.

    A blocked simulator (``method="blocked"``, what ``"auto"`` picks when it can) scores from Pearson
    sums of block Gram matrices without forming the outputs (:mod:`jaxheli.sim.pearson_sums`), its population
    spread over the local devices when there are several (``shard``, see :func:`jaxheli.sim.shard.map_population`);
    a scan simulator simulates every sample and scores the outputs. Both give the same cost up to rounding.
    """
    thetas = jnp.asarray(thetas)
    if sim.method != "blocked":
        return paper_cost(sim(thetas), target)
    flat = thetas.reshape((-1, thetas.shape[-1]))
    arrays, settings = eqx.partition(sim, eqx.is_array)

    def local(part: Array, arrays: Simulator, target: Array) -> Array:
        return blocked_cost(eqx.combine(arrays, settings), part, target)

    cost = map_population(local, flat, arrays, jnp.asarray(target), shard=shard)
    return cost.reshape(thetas.shape[:-1])


class PopulationCost(eqx.Module):
    """``thetas[P, 40] -> cost[P]``: the search cost ``kind`` on one flight, scored in ``precision`` and returned
    in the candidates' dtype. The paper's cost (``"pearson"``) runs on the fastest kernel the simulator has
    (:func:`simulator_cost`); ``"output-error"`` (:func:`jaxheli.cost.output_error_cost`) on its outputs.

    A pytree (the flight's arrays are leaves), so it stays traced inside an optimiser's scan and one compiled
    run serves every flight of the same length. ``precision`` ``None`` scores in the candidates' dtype.
    """

    sim: Simulator
    target: Float[Array, "N k"]
    precision: str | None = eqx.field(static=True, default=None)
    kind: SearchCost = eqx.field(static=True, default="pearson")

    def __call__(self, thetas: Population) -> Float[Array, "P"]:
        thetas = jnp.asarray(thetas)
        dtype = thetas.dtype if self.precision is None else self.precision
        candidates, target = thetas.astype(dtype), self.target.astype(dtype)
        if self.kind == "pearson":
            cost = simulator_cost(self.sim, candidates, target)
        else:
            cost = _output_cost(self.sim, candidates, target, self.kind)
        return cost.astype(thetas.dtype)


@eqx.filter_jit
def _output_cost(sim: Simulator, thetas: Array, target: Array, kind: SearchCost) -> Array:
    return search_cost(kind, sim(thetas), target)


def population_cost(thetas: Population, data: FlightData | Any, **options) -> Float[Array, "pop"]:
    """The paper's cost (Eq. 7) for every candidate of ``thetas[P, 40]``, one jitted call.

    ``data`` is a flight, with the options of :func:`jaxheli.make_simulator` (``outputs``, ``hold``,
    ``segment``, ...; the cost runs over the chosen output channels), or a :class:`jaxheli.problem.Problem`
    (no options: its settings hold, the search cost they name included). Diverging candidates get the worst
    cost (``4 k`` for the paper's, ``inf`` for the output error).
    """
    if isinstance(data, FlightData):
        sim = make_simulator(data, **options)
        return simulator_cost(sim, jnp.asarray(thetas), jnp.asarray(data.select(sim.outputs).outputs))
    if options:
        raise ValueError(f"population_cost: options {sorted(options)} go with a flight, not a Problem")
    return data.population_cost()(jnp.asarray(thetas))
