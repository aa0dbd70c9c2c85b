"""Runs started from their least-squares states (variable projection) against a numpy/scipy reference and against
the projection they replaced (powers of ``Ad`` at every sample)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.data.flight import FlightData
from jaxheli.model import TABLE2, build_ab, output_indices
from jaxheli.optim.pem import pem_residuals, residuals
from jaxheli.problem import make_problem
from jaxheli.sim.discretize import discretize
from jaxheli.sim.shooting import RIDGE, run_layout, run_states
from jaxheli.sim.simulate import make_simulator
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import piloted_flight

from numpy_reference import estimated_runs

OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")


@pytest.fixture(scope="module")
def flight():
    return piloted_flight(TABLE2, duration=12.0, dt=0.02, excitation=Excitation("3211", unit=0.3), seed=3)


@pytest.mark.parametrize("segment", [None, 1.0, 0.7])
def test_estimated_runs_match_a_numpy_reference(flight, segment):
    sim = make_simulator(flight, outputs=OUTPUTS, x0="estimated", segment=segment)
    ref, starts = estimated_runs(TABLE2, flight, segment, OUTPUTS)
    np.testing.assert_allclose(np.asarray(sim(TABLE2)), ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    np.testing.assert_allclose(np.asarray(run_states(sim, TABLE2)), starts, rtol=1e-7, atol=1e-9)
    assert sim.method == "scan" and "least-squares state" in sim.describe()["mode"]


def test_noise_free_runs_from_unknown_states_are_reproduced(flight):
    """A record whose state jumps at every restart (each run from its own random state) is fitted exactly."""
    sim = make_simulator(flight, outputs=OUTPUTS, segment=1.0)
    rng = np.random.default_rng(0)
    sample, valid = run_layout(flight.n_samples, sim.segment_samples)
    y = np.zeros((flight.n_samples, len(OUTPUTS)))
    for j, x0 in enumerate(rng.normal(0.0, 0.2, (sample.shape[0], 13))):
        begin = sample[j][valid[j]][0] - (1 if j else 0)
        part = FlightData(flight.time[begin:], flight.inputs[begin:], flight.outputs[begin:], flight.output_names)
        run = np.asarray(make_simulator(part, outputs=OUTPUTS, x0=x0)(TABLE2))
        y[sample[j][valid[j]]] = run[sample[j][valid[j]] - begin]
    clean = flight.replace(outputs=y, output_names=OUTPUTS)
    fitted = make_simulator(clean, outputs=OUTPUTS, x0="estimated", segment=1.0)
    np.testing.assert_allclose(np.asarray(fitted(TABLE2)), y, atol=1e-6 * np.abs(y).max())


def test_layout_and_errors():
    sample, valid = run_layout(11, 4)  # runs: 0..4, 5..8, 9..10
    assert sample.shape == (3, 5) and valid.sum() == 11
    assert sorted(sample[valid].tolist()) == list(range(11))
    f = piloted_flight(TABLE2, duration=12.0, dt=0.02, excitation=Excitation("3211", unit=0.3), seed=1)
    with pytest.raises(ValueError, match="blocked"):
        make_simulator(f, x0="estimated", method="blocked")
    with pytest.raises(ValueError, match="estimated initial states"):
        make_simulator(f, x0="estimated").states(TABLE2)


def _summed_powers_outputs(sim, theta):
    """The projection as it was (158f28b): ``C Ad^m`` at every step, each run's Gram matrix and right-hand side
    summed over its samples; the runs from rest by the simulator's restarts."""
    idx = output_indices(sim.outputs)
    measured = sim.measured_states[:, idx]
    std = jnp.std(measured, axis=0)
    used = jnp.asarray(np.asarray(sim.measured_mask)[idx]) & (std > 0)
    weight = jnp.where(used, 1.0 / jnp.where(std > 0, std, 1.0) ** 2, 0.0)
    zeros = jnp.zeros_like(sim.measured_states)
    forced = dataclasses.replace(sim, measured_states=zeros, x0=zeros[0], initial="given", reset="zero")._one(theta)
    Ad = discretize(*build_ab(theta, sim.g), sim.dt, sim.hold).Ad
    eye = jnp.eye(13, dtype=Ad.dtype)
    sample, valid = run_layout(measured.shape[0], sim.restart_samples)
    _, powers = jax.lax.scan(lambda M, _: (Ad @ M, M[idx]), eye, None, length=sample.shape[1])  # [L + 1, k, 13]
    error = jnp.concatenate([measured - forced, jnp.zeros((1, idx.size))])[sample]
    weighted = powers * weight[None, :, None]
    gram = jnp.einsum("jm,mkx,mky->jxy", jnp.asarray(valid, float), weighted, powers)
    rhs = jnp.einsum("jmk,mkx->jx", error, weighted)
    scale = RIDGE * jnp.trace(gram, axis1=-2, axis2=-1) / 13
    x0 = jnp.linalg.solve(gram + scale[:, None, None] * eye[None], rhs[..., None])[..., 0]
    free = jnp.einsum("mkx,jx->jmk", powers, x0).reshape(-1, idx.size)
    return forced + jnp.zeros((forced.shape[0] + 1, idx.size)).at[sample.ravel()].add(free)[:-1]


@pytest.mark.parametrize("segment", [None, 1.0, 0.7])
def test_objective_and_gradient_match_the_summed_powers(flight, segment):
    """The output-error objective (the polish's) and its gradient agree with the projection it replaced.

    The candidates are within 5 % of Table 2, where every run's Gram matrix has a condition number near 3e5. Where
    the ridge bounds it (near 1e11, e.g. 10 % off, seed 5, fourth draw, one run) neither computation holds the
    initial state to 1e-9: against a 60-digit solve of the same sums its relative error was 7e-7 summed, 2e-7
    doubled, and the gradients differed by 6e-9 of their largest entry."""
    problem = make_problem(flight, outputs=OUTPUTS, x0="estimated", segment=segment, simulator="scan")
    rng = np.random.default_rng(5)
    thetas = [TABLE2] + [TABLE2 * (1.0 + 0.05 * rng.standard_normal(40)) for _ in range(3)]

    def new(theta):
        return jnp.sum(residuals(problem, theta) ** 2)

    def old(theta):
        return jnp.sum(pem_residuals(problem, _summed_powers_outputs(problem.sim, theta)) ** 2)

    new_and_grad, old_and_grad = jax.jit(jax.value_and_grad(new)), jax.jit(jax.value_and_grad(old))
    for theta in thetas:
        (v_new, g_new), (v_old, g_old) = new_and_grad(jnp.asarray(theta)), old_and_grad(jnp.asarray(theta))
        np.testing.assert_allclose(v_new, v_old, rtol=1e-9)
        np.testing.assert_allclose(g_new, g_old, rtol=1e-9, atol=1e-9 * np.abs(g_old).max())
