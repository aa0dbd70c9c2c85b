"""GA: analytic minima in a box (pinned axes stay pinned, bounds hold), elitism, NaN safety, schedule."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.optimize

from jaxheli.optim._base import Candidates
from jaxheli.optim.ga import GA
from jaxheli.optim.run import minimize
from problems import HI6, HOLEY, LO6, SHIFT, SPHERE, Rosenbrock

# Rosenbrock in 6 dimensions, axis 1 pinned at the optimum's value 1 and axis 4 pinned off it (at 0.5);
# the box excludes the local minimum near x0 = -1.
LO_R, HI_R = -0.5 * np.ones(6), 2.0 * np.ones(6)
LO_R[1] = HI_R[1] = 1.0
LO_R[4] = HI_R[4] = 0.5


OPT6 = GA(LO6, HI6, iterations=200)
rosenbrock = Rosenbrock(LO_R, HI_R)


def test_finds_shifted_sphere():
    result = minimize(OPT6, SPHERE, jax.random.key(0), progress=False)
    np.testing.assert_allclose(result.best_theta, SHIFT, atol=1e-3)
    history = np.asarray(result.history)
    assert history.shape == (200,) and np.all(np.diff(history) <= 0)
    assert int(result.n_evaluations) == 40 + 200 * 38


def test_rosenbrock_with_pinned_axes():
    opt = GA(LO_R, HI_R, iterations=400)
    result = minimize(opt, rosenbrock, jax.random.key(1), progress=False)
    best = np.asarray(result.best_theta)
    assert best[1] == 1.0 and best[4] == 0.5
    assert np.all(np.asarray(opt.to_theta(result.state.population))[:, [1, 4]] == [1.0, 0.5])
    # reference: scipy on the four free axes (the pinned x4 = 0.5 moves the minimiser off all-ones)
    free = [0, 2, 3, 5]

    def objective(x):
        theta = np.array([x[0], 1.0, x[1], x[2], 0.5, x[3]])
        return float(rosenbrock(jnp.asarray(theta)[None])[0])

    ref = scipy.optimize.minimize(objective, np.ones(4), method="L-BFGS-B", bounds=[(-0.5, 2)] * 4, tol=1e-12)
    assert float(result.best_cost) < ref.fun + 1e-3
    np.testing.assert_allclose(best[free], ref.x, atol=0.01)


def test_non_finite_costs_never_best():
    result = minimize(OPT6, HOLEY, jax.random.key(2), iterations=100, progress=False)
    best = np.asarray(result.best_theta)
    assert np.isfinite(float(result.best_cost))
    assert best[0] <= 1.0 and best[1] <= 2.0 and best[2] >= -3.0
    assert float(HOLEY(result.best_theta[None])[0]) == float(result.best_cost)
    assert np.all(np.isfinite(np.asarray(result.history)))
    assert not np.any(np.isnan(np.asarray(result.state.costs)))


def test_elite_survive_a_generation():
    """The two best parents outlive worse children; a better child goes first."""
    state = minimize(OPT6, SPHERE, jax.random.key(4), iterations=0, progress=False).state
    unit = jnp.asarray(np.random.default_rng(0).uniform(size=(38, 6)))
    costs = jnp.full(38, 1e9).at[5].set(-1.0)
    nxt = eqx.filter_jit(OPT6.tell)(state, Candidates(unit, OPT6.to_theta(unit), jnp.ones(38, bool)), costs)
    np.testing.assert_array_equal(nxt.population[0], unit[5])
    np.testing.assert_array_equal(nxt.population[1:3], state.population[:2])
    np.testing.assert_array_equal(nxt.costs[:3], [-1.0, state.costs[0], state.costs[1]])
    assert float(nxt.best_cost) == -1.0 and int(nxt.n_evaluations) == 40 + 38


def test_mutation_schedule_is_geometric():
    opt = GA(LO6, HI6, iterations=101, sigma_initial=0.1, sigma_final=0.001)
    assert float(opt.sigma(1)) == pytest.approx(0.1)
    assert float(opt.sigma(51)) == pytest.approx(0.01)
    assert float(opt.sigma(101)) == pytest.approx(0.001)
    assert float(opt.sigma(500)) == pytest.approx(0.001)


def test_bad_settings_rejected():
    with pytest.raises(ValueError):
        GA(LO6, HI6, elite=40)
    with pytest.raises(ValueError):
        GA(LO6, np.ones(5))
