"""The paper's cost for a whole population of candidates in one jitted call."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .._types import Array, Float, Population
from ..cost import paper_cost
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


def population_cost(thetas: Population, flight: FlightData, **options) -> Float[Array, "pop"]:
    """The paper's cost (Eq. 7) for every candidate of ``thetas[P, 40]``, one jitted call.

    Options are those of :func:`jaxheli.make_simulator` (``outputs``, ``hold``, ``segment``, ...); the cost
    runs over the chosen output channels. Diverging candidates get the worst cost ``4 k``.
    """
    sim = make_simulator(flight, **options)
    target = jnp.asarray(flight.select(sim.outputs).outputs)
    return simulator_cost(sim, jnp.asarray(thetas), target)
