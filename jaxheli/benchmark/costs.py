"""Evaluations per second of each cost the engines minimise, as ratios to the paper's Pearson cost in the same run.

One flight, one population of candidates drawn in the box, each cost jitted over the whole population and timed
as the best of ``repeats`` calls after a warm-up (compilation excluded): the paper's Pearson cost and the output
error of one run from rest (the population engines' search costs), the output error with every run from its
least-squares state (the polish: one run, and 5 s runs; :mod:`jaxheli.sim.shooting`) and Tischler's average ``J``
on the flight's frequency-response bins (the frequency fit; the spectra are estimated once, outside the timing;
every bin of the default band is scored, whatever its coherence, so the time does not depend on the flight's).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..data.flight import FlightData
from ..optim.frequency_fit import average_j, frequency_targets
from ..optim.pem import residuals
from ..problem import Problem, make_problem
from .throughput import best_seconds, candidates


@eqx.filter_jit
def _sum_of_squares(problem: Problem, thetas: jax.Array) -> jax.Array:
    return jax.lax.map(lambda theta: jnp.sum(residuals(problem, theta) ** 2), thetas)


@eqx.filter_jit
def _j(targets: tuple, thetas: jax.Array) -> jax.Array:
    return jax.lax.map(lambda theta: average_j(targets, theta), thetas)


def cost_rates(flight: FlightData, count: int, repeats: int) -> list[dict]:
    """``[{"cost", "rate" (candidates/s), "ratio" (to the Pearson cost)}]`` on ``flight`` for ``count`` candidates
    (float64, the precision of the polish and the frequency fit)."""
    problem = make_problem(flight, precision="float64", simulator="scan")
    thetas = candidates(count, jnp.float64)
    targets = frequency_targets(problem, min_coherence=0.0, min_bins=1)
    costs = {
        "Pearson, one run from rest (paper Eq. 7; IWO / GA)": problem.population_cost(),
        "output error, one run from rest (IWO / GA --cost output-error)":
            problem.variant(cost="output-error").population_cost(),
        "output error, estimated initial state, one run (polish)":
            lambda th: _sum_of_squares(problem.variant(x0="estimated"), th),
        "output error, estimated initial states, 5 s runs (polish)":
            lambda th: _sum_of_squares(problem.variant(x0="estimated", segment=5.0), th),
        "Tischler's J on the flight's frequency responses (frequency fit)": lambda th: _j(targets, th),
    }
    rows = [{"cost": name, "rate": count / best_seconds(lambda f=fn: f(thetas), repeats)} for name, fn in costs.items()]
    for row in rows:
        row["ratio"] = row["rate"] / rows[0]["rate"]
        print(f"cost {row['cost']}: {row['rate']:.0f} candidates/s ({row['ratio']:.2f}x Pearson)", flush=True)
    return rows
