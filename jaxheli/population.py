"""The paper's cost for a whole population of candidates in one jitted call."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from ._types import Array, Float, Population
from .cost import paper_cost
from .flight import FlightData
from .simulate import Simulator, make_simulator


@eqx.filter_jit
def simulator_cost(sim: Simulator, thetas: Array, target: Array) -> Array:
    """Paper cost of ``thetas[P, 40]`` under a prepared simulator against ``target[N, k]``."""
    return paper_cost(sim(thetas), target)


def population_cost(thetas: Population, flight: FlightData, **options) -> Float[Array, "pop"]:
    """The paper's cost (Eq. 7) for every candidate of ``thetas[P, 40]``, one jitted call.

    Options are those of :func:`jaxheli.make_simulator` (``outputs``, ``hold``, ``segment``, ...); the cost
    runs over the chosen output channels. Diverging candidates get the worst cost ``4 k``.
    """
    sim = make_simulator(flight, **options)
    target = jnp.asarray(flight.select(sim.outputs).outputs)
    return simulator_cost(sim, jnp.asarray(thetas), target)
