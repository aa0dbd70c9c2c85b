"""IWO: the sigma schedule and seed counts against their formulas, analytic minima in a box, NaN safety,
competitive exclusion, and a small helicopter recovery on a synthetic flight."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, PARAM_NAMES, TABLE2, UPPER
from jaxheli.optim._base import Candidates, score
from jaxheli.optim.iwo import IWO, IWOState, _seed_counts
from jaxheli.optim.run import minimize, minimize_trials
from problems import HI6, HOLEY, LO6, SHIFT, SPHERE, Rosenbrock
from jaxheli.sim.population import simulator_cost
from jaxheli.sim.simulate import make_simulator, simulate

# Rosenbrock in 8 dimensions with axes 2 and 5 pinned at the optimum's value 1; the box excludes the
# local minimum near x0 = -1.
LO8, HI8 = -0.5 * np.ones(8), 2.0 * np.ones(8)
LO8[[2, 5]] = HI8[[2, 5]] = 1.0


OPT6 = IWO(LO6, HI6, iterations=300, modulation=3.0)
rosenbrock = Rosenbrock(LO8, HI8)


def test_sigma_matches_formula():
    opt = IWO(LO6, HI6, iterations=200, modulation=0.5, sigma_initial=0.9, sigma_final=0.001)
    for g in (0, 1, 2, 37, 100, 199, 200, 250):
        left = max(200 - g, 0) / 200
        expected = left**0.5 * (0.9 - 0.001) + 0.001
        assert float(opt.sigma(g)) == pytest.approx(expected, rel=1e-12)
    assert float(opt.sigma(200)) == pytest.approx(0.001, rel=1e-12)
    assert jnp.all(jnp.diff(opt.sigma(jnp.arange(1, 201))) < 0)


def test_dispersal_spread_follows_schedule():
    """Seeds scatter around their parent with the scheduled sigma (per bound width in absolute units)."""
    lower, upper = np.zeros(4), np.array([1.0, 2.0, 5.0, 10.0])
    unit = IWO(lower, upper, iterations=100, sigma_initial=0.3, sigma_final=0.01)
    # every slot alive at the centre with equal cost: 40 plants x 7 seeds, none clipped
    state = IWOState(population=jnp.full((40, 4), 0.5), costs=jnp.zeros(40), alive=jnp.ones(40, bool),
                     key=jax.random.key_data(jax.random.key(3)), iteration=jnp.asarray(94),
                     best_theta=jnp.zeros(4), best_cost=jnp.asarray(0.0), n_evaluations=jnp.asarray(0))
    sigma = float(unit.sigma(95))
    for opt, expected in ((unit, np.full(4, sigma)),
                          (dataclasses.replace(unit, sigma_units="absolute"), sigma / (upper - lower))):
        seeds = eqx.filter_jit(opt.ask)(state)
        assert bool(jnp.all(seeds.real))
        np.testing.assert_allclose(np.std(np.asarray(seeds.unit) - 0.5, axis=0), expected, rtol=0.12)


def test_seed_counts_linear_in_fitness():
    counts_of = jax.jit(_seed_counts, static_argnums=(2, 3))
    costs = jnp.array([1.0, 2.0, 3.0, 5.0, jnp.inf, 0.5, 4.0])
    alive = jnp.array([True, True, True, True, True, False, True])
    # best (1) -> 7, worst finite (5) -> 2, linear in between, floored; inf -> min; dead (even if cheap) -> 0
    assert np.asarray(counts_of(costs, alive, 2, 7)).tolist() == [7, 5, 4, 2, 2, 0, 3]
    c = np.random.default_rng(0).uniform(-3, 8, 40)
    expected = np.floor(2 + 5 * ((c.max() - c) / (c.max() - c.min())))
    np.testing.assert_array_equal(counts_of(jnp.asarray(c), jnp.ones(40, bool), 2, 7), expected)
    assert np.asarray(counts_of(jnp.full(40, 3.0), jnp.ones(40, bool), 2, 7)).tolist() == [7] * 40
    assert np.asarray(counts_of(jnp.full(40, jnp.inf), jnp.ones(40, bool), 2, 7)).tolist() == [2] * 40


def test_all_survive_until_population_full():
    """Before the cap, every seed survives, even with an infinite cost; the seeds are scored max_population at a
    time (a traced cost call per batch size)."""
    shapes = []

    def cost(thetas):
        shapes.append(thetas.shape)
        return jnp.where(thetas[:, 0] > 0.0, jnp.inf, jnp.sum(thetas**2, axis=1))

    opt = IWO(LO6, HI6, initial_population=3, max_population=40)
    unit = jnp.asarray([[0.1] * 6, [0.6] * 6, [0.3] * 6])  # the middle one has an infinite cost
    first = Candidates(unit, opt.to_theta(unit), jnp.ones(3, bool))
    state = eqx.filter_jit(opt.init_tell)(jax.random.key_data(jax.random.key(0)), first, cost(first.theta))
    assert int(jnp.sum(state.alive)) == 3 and np.isinf(float(state.costs[2]))
    n_seeds = int(jnp.sum(_seed_counts(state.costs, state.alive, 2, 7)))
    state = eqx.filter_jit(opt.step)(state, cost)
    assert shapes[0] == (3, 6) and set(shapes[1:]) == {(40, 6)}
    assert int(jnp.sum(state.alive)) == 3 + n_seeds < 40
    assert int(state.n_evaluations) == 3 + n_seeds
    costs = np.asarray(state.costs)
    assert np.all(costs[:-1] <= costs[1:])
    assert not np.any(np.isfinite(costs)[~np.asarray(state.alive)])


def test_finds_shifted_sphere():
    result = minimize(OPT6, SPHERE, jax.random.key(0), progress=False)
    np.testing.assert_allclose(result.best_theta, SHIFT, atol=0.03)
    assert result.history.shape == (300,)
    assert np.all(np.diff(np.asarray(result.history)) <= 0)
    assert float(result.history[-1]) == float(result.best_cost) < 1e-3


def test_rosenbrock_with_pinned_axes():
    opt = IWO(LO8, HI8, iterations=300, modulation=3.0)
    result = minimize(opt, rosenbrock, jax.random.key(1), progress=False)
    assert float(result.best_cost) < 5e-3
    np.testing.assert_allclose(result.best_theta, np.ones(8), atol=0.02)
    assert np.all(np.asarray(result.best_theta)[[2, 5]] == 1.0)
    assert np.all(np.asarray(opt.to_theta(result.state.population))[:, [2, 5]] == 1.0)


def test_non_finite_costs_never_best():
    result = minimize(OPT6, HOLEY, jax.random.key(2), iterations=100, progress=False)
    best = np.asarray(result.best_theta)
    assert np.isfinite(float(result.best_cost))
    assert best[0] <= 1.0 and best[1] <= 2.0 and best[2] >= -3.0
    assert float(HOLEY(result.best_theta[None])[0]) == float(result.best_cost)
    assert np.all(np.isfinite(np.asarray(result.history)))
    assert not np.any(np.isnan(np.asarray(result.state.costs)))


def test_all_nan_costs_never_crash():
    """A population that only ever sees NaN: nothing becomes best, every plant still lives and sows."""
    unit = jnp.asarray(np.random.default_rng(0).uniform(size=(280, 6)))
    nan = jnp.full(280, jnp.nan)
    first = Candidates(unit[:20], OPT6.to_theta(unit[:20]), jnp.ones(20, bool))
    state = eqx.filter_jit(OPT6.init_tell)(jax.random.key_data(jax.random.key(0)), first, nan[:20])
    assert np.isinf(float(state.best_cost)) and int(jnp.sum(state.alive)) == 20
    seeds = Candidates(unit, OPT6.to_theta(unit), jnp.arange(280) < 100)
    state = eqx.filter_jit(OPT6.tell)(state, seeds, nan)
    assert np.isinf(float(state.best_cost)) and not np.any(np.isnan(np.asarray(state.costs)))
    assert int(jnp.sum(state.alive)) == 40 and np.all(np.isfinite(np.asarray(state.best_theta)))
    assert np.all(np.asarray(_seed_counts(state.costs, state.alive, 2, 7)) == 2)


def test_bad_settings_rejected():
    with pytest.raises(ValueError):
        IWO(LO6, HI6, initial_population=50)
    with pytest.raises(ValueError):
        IWO(HI6, LO6)
    with pytest.raises(ValueError):
        IWO(LO6, HI6, sigma_units="metres")


def _heli_cost(sim, target, thetas):
    return simulator_cost(sim, thetas, target)


def test_recovers_helicopter_parameters():
    """Synthetic flight of Table 2 under sine sticks, 0.5 % noise; 8 free parameters in +-20 % boxes, the
    other 32 pinned at the truth. The paper's IWO settings, 100 generations."""
    t = np.arange(0.0, 4.0, 0.02)
    sticks = np.stack([0.05 * np.sin(2 * np.pi * 0.7 * t), 0.05 * np.sin(2 * np.pi * 0.45 * t + 1.0),
                       0.03 * np.sin(2 * np.pi * 0.3 * t), 0.03 * np.sin(2 * np.pi * 0.9 * t + 2.0)], axis=1)
    flight = FlightData(t, sticks, np.zeros((t.size, 4)), ("p", "q", "phi", "theta"))
    clean = np.asarray(simulate(TABLE2, flight))
    noisy = clean + 0.005 * clean.std(axis=0) * np.random.default_rng(0).standard_normal(clean.shape)
    flight = flight.replace(outputs=noisy)
    idx = [PARAM_NAMES.index(n) for n in ("Lb", "Ma", "tf", "Alat", "Alon", "Blat", "Blon", "Ab")]
    lower, upper = TABLE2.copy(), TABLE2.copy()
    lower[idx] = np.minimum(0.8 * TABLE2[idx], 1.2 * TABLE2[idx])
    upper[idx] = np.maximum(0.8 * TABLE2[idx], 1.2 * TABLE2[idx])
    cost = eqx.Partial(_heli_cost, make_simulator(flight), jnp.asarray(noisy))

    opt = IWO(lower, upper, iterations=100)
    start = minimize(opt, cost, jax.random.key(0), iterations=0, progress=False)
    result = minimize(opt, cost, jax.random.key(0), progress=False)
    assert start.history.shape == (0,)
    assert float(result.best_cost) < 0.1 * float(start.best_cost)
    best = np.asarray(result.best_theta)
    assert np.all((best >= lower) & (best <= upper))
    pinned = np.setdiff1d(np.arange(40), idx)
    np.testing.assert_array_equal(best[pinned], TABLE2[pinned])


class _WholeBuffer(IWO):
    """IWO scoring its whole seed buffer in one cost call per generation (the path before issue 18)."""

    @property
    def score_batch(self) -> None:
        return None


def test_scoring_real_seeds_only_matches_the_whole_buffer():
    """Scoring only the real seeds, max_population at a time, runs the same search as one cost call on the whole
    buffer (padding included), to 1e-6: all 40 parameters in the authors' box, a helicopter flight, float64,
    one run and three vmapped trials."""
    t = np.arange(0.0, 3.0, 0.02)
    sticks = np.stack([0.05 * np.sin(2 * np.pi * 0.7 * t), 0.05 * np.sin(2 * np.pi * 0.45 * t + 1.0),
                       0.03 * np.sin(2 * np.pi * 0.3 * t), 0.03 * np.sin(2 * np.pi * 0.9 * t + 2.0)], axis=1)
    flight = FlightData(t, sticks, np.zeros((t.size, 4)), ("p", "q", "phi", "theta"))
    clean = np.asarray(simulate(TABLE2, flight))
    cost = eqx.Partial(_heli_cost, make_simulator(flight), jnp.asarray(clean))
    compact, whole = IWO(LOWER, UPPER, iterations=30), _WholeBuffer(LOWER, UPPER, iterations=30)
    assert compact.score_batch == 40 * jax.local_device_count() and whole.score_batch is None

    state = minimize(compact, cost, jax.random.key(3), iterations=5, progress=False).state
    seeds = compact.ask(state)
    assert 0 < int(jnp.sum(seeds.real)) < 280  # padding present: batches without real seeds are skipped
    np.testing.assert_allclose(score(cost, seeds, 40), score(cost, seeds, None), rtol=1e-6)
    np.testing.assert_allclose(score(cost, seeds, 80), score(cost, seeds, None), rtol=1e-6)
    assert np.all(np.isinf(np.asarray(score(cost, seeds, 40))[~np.asarray(seeds.real)]))

    for run in (lambda opt: minimize(opt, cost, jax.random.key(3), progress=False),
                lambda opt: minimize_trials(opt, cost, jax.random.split(jax.random.key(3), 3), progress=False)):
        a, b = run(compact), run(whole)
        np.testing.assert_allclose(a.history, b.history, rtol=1e-6)
        np.testing.assert_allclose(a.best_theta, b.best_theta, rtol=1e-6)
        np.testing.assert_array_equal(a.n_evaluations, b.n_evaluations)
