"""The box-constrained Levenberg-Marquardt / Gauss-Newton of the least-squares engines against scipy's bounded
least squares (``lsq_linear`` and the trust-region-reflective ``least_squares``), and never outside the box; the
engines' driver (penalty past the box, the start kept unless the answer is better)."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest
import scipy.optimize

from jaxheli.bounds import Bounds
from jaxheli.optim.boxed_lm import BoxedLeastSquares, boxed_least_squares, least_squares_solver


def _solve(fn, y0, n_bounded, solver="lm", args=None, max_steps=200):
    sol = optx.least_squares(fn, BoxedLeastSquares(1e-10, 1e-10, n_bounded, solver), jnp.asarray(y0), args=args,
                             max_steps=max_steps, throw=False)
    return np.asarray(sol.value), sol


def _in_box(y, n_bounded):
    """``y`` unchanged, or a runtime error if a bounded entry lies outside ``[0, 1]``."""
    u = y[:n_bounded]
    return eqx.error_if(y, jnp.any((u < 0.0) | (u > 1.0)), "a residual was evaluated outside the box")


@pytest.fixture(scope="module")
def linear():
    """A 60 x 6 linear problem whose unbounded answer lies outside the unit box on several axes."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(60, 6))
    x_free = np.array([-0.4, 0.3, 1.7, 0.6, 2.5, -1.0])
    return a, a @ x_free + 0.01 * rng.normal(size=60)


@pytest.mark.parametrize("solver", ["lm", "gn"])
def test_linear_box_least_squares_matches_scipy(linear, solver):
    a, b = linear
    expected = scipy.optimize.lsq_linear(a, b, bounds=(0.0, 1.0), tol=1e-14).x
    got, sol = _solve(lambda y, _: a @ _in_box(y, 6) - b, np.full(6, 0.5), 6, solver)
    assert sol.result == optx.RESULTS.successful
    np.testing.assert_allclose(got, expected, atol=1e-7)
    assert {0, 4, 5} <= set(np.flatnonzero((got == 0.0) | (got == 1.0)))


def test_nonlinear_fit_with_an_active_bound_matches_scipy_trf():
    """``c0 exp(-c1 t) + c2 + c3 t`` with the decay rate capped below its unbounded optimum; the slope ``c3``
    is unbounded (as a fitted initial state is) and its optimum lies outside ``[0, 1]``."""
    t = np.linspace(0.0, 4.0, 80)
    data = 0.8 * np.exp(-1.6 * t) + 0.2 - 1.5 * t

    def res(y, _):
        y = _in_box(y, 3)
        return y[0] * jnp.exp(-y[1] * t) + y[2] + y[3] * t - data

    lower, upper = np.array([0.0, 0.0, 0.0, -np.inf]), np.array([1.0, 1.0, 1.0, np.inf])
    expected = scipy.optimize.least_squares(lambda y: np.asarray(res(jnp.asarray(y), None)), [0.5, 0.5, 0.5, 0.0],
                                            bounds=(lower, upper), method="trf", xtol=1e-14, ftol=1e-14,
                                            gtol=1e-14).x
    got, _ = _solve(res, [0.5, 0.5, 0.5, 0.0], 3)
    assert got[1] == 1.0  # the decay rate is held at its bound
    np.testing.assert_allclose(got, expected, atol=1e-6)


def test_an_axis_leaves_a_bound_when_its_gradient_turns():
    """Started on the lower bound of an axis whose optimum is inside: the active set releases it."""
    got, _ = _solve(lambda y, _: jnp.stack([_in_box(y, 2)[0] - 0.3, 10.0 * (y[1] - y[0] ** 2)]), [0.0, 1.0], 2)
    np.testing.assert_allclose(got, [0.3, 0.09], atol=1e-8)


def test_unbounded_tail_is_not_clipped():
    got, _ = _solve(lambda y, _: jnp.stack([y[0] - 2.0, y[1] + 3.0]), [0.5, 0.0], 1)
    np.testing.assert_allclose(got, [1.0, -3.0], atol=1e-10)


def test_bad_solver_name():
    with pytest.raises(ValueError, match="'lm' or 'gn'"):
        BoxedLeastSquares(1e-8, 1e-8, 1, "newton")


def test_driver_answer_lies_in_the_box_and_matches_scipy(linear):
    """The penalty pulls the first pass's iterates back towards the box (its answer ~1e-5 past the active bounds);
    the second pass, from that answer clipped, re-solves the free axes with the active ones held: scipy's answer."""
    a, b = linear
    expected = scipy.optimize.lsq_linear(a, b, bounds=(0.0, 1.0), tol=1e-14).x
    u0 = jnp.full(6, 0.5)
    sol = boxed_least_squares(lambda u, _: a @ u - b, least_squares_solver("lm", 1e-10, 1e-10, 6), u0, None, 200)
    got = np.asarray(sol.value)
    assert bool(sol.improved) and float(sol.loss[1]) < float(sol.loss[0])
    assert np.all((got >= 0.0) & (got <= 1.0)) and {0, 4, 5} <= set(np.flatnonzero((got == 0.0) | (got == 1.0)))
    np.testing.assert_allclose(got, expected, atol=1e-8)
    start_loss = np.sum((a @ np.asarray(u0) - b) ** 2)  # the default score: the penalised sum of squares
    np.testing.assert_allclose(float(sol.loss[0]), start_loss, rtol=1e-12)


def _first_pass_clipped(fn, solver, u0, max_steps):
    """The answer of the driver's first pass alone (steps within the solver's margin), clipped into the box."""
    def penalised(u, args):
        return jnp.concatenate([fn(u, args), Bounds.penalty(u)])

    sol = optx.least_squares(penalised, solver, u0, max_steps=max_steps, throw=False)
    return np.asarray(Bounds.clip_unit(sol.value)), np.asarray(sol.value)


@pytest.mark.parametrize(("solver", "steps"), [("lm", 200), ("gn", 8), ("gn", 200)])
def test_no_driver_answer_lies_outside_the_box_or_scores_worse_than_the_clipped_one(solver, steps):
    """A nonlinear fit whose unbounded optimum lies outside the box (its amplitude), stopped early and converged: the
    driver's answer lies in the box and its sum of squares is no larger than the first pass's answer clipped."""
    t = np.linspace(0.0, 3.0, 90)
    data = 1.3 * np.exp(-0.7 * t) * np.cos(2.0 * t) - 0.1 + 0.02 * np.sin(17.0 * t)

    def res(u, _):
        return 1.1 * u[0] * jnp.exp(-2.0 * u[1] * t) * jnp.cos(3.0 * u[2] * t) + u[3] - 0.5 - data

    fit = least_squares_solver(solver, 1e-12, 1e-12, 4)
    u0 = jnp.array([0.5, 0.5, 0.5, 0.5])
    clipped, raw = _first_pass_clipped(res, fit, u0, steps)
    assert np.any(raw < 0.0) or np.any(raw > 1.0)  # the case in question: the first answer lies outside
    sol = boxed_least_squares(res, fit, u0, None, steps)
    got = np.asarray(sol.value)
    assert bool(sol.improved) and np.all((got >= 0.0) & (got <= 1.0))
    assert np.sum(np.asarray(res(got, None)) ** 2) <= np.sum(np.asarray(res(clipped, None)) ** 2)


def test_driver_keeps_the_start_unless_the_answer_scores_no_worse(linear):
    a, b = linear
    u0 = jnp.full(6, 0.5)

    def worse(start, answer, _):
        """Rates the answer worse than the start, whatever it is."""
        return jnp.stack([0.0, 1.0]), (start, Bounds.clip_unit(answer))

    sol = boxed_least_squares(lambda u, _: a @ u - b, least_squares_solver("lm", 1e-10, 1e-10, 6), u0, None, 200,
                              worse)
    assert not bool(sol.improved) and int(sol.num_steps) > 0
    np.testing.assert_array_equal(np.asarray(sol.value), np.asarray(u0))
    np.testing.assert_array_equal(np.asarray(sol.kept(*sol.aux)), np.asarray(u0))


@pytest.mark.parametrize("steps", [1, 3, 7])
def test_a_run_time_step_limit_equals_the_compiled_one(steps):
    """``limit`` under a larger compiled ``max_steps`` stops after the same steps at the same point, reported as
    reaching the limit, as ``max_steps=limit`` itself; one compiled solve serves every limit."""
    t = np.linspace(0.0, 4.0, 80)
    data = 0.8 * np.exp(-1.6 * t) + 0.2 - 1.5 * t

    def res(u, _):
        return u[0] * jnp.exp(-4.0 * u[1] * t) + u[2] - 2.0 * u[3] * t - data

    solver, u0 = least_squares_solver("lm", 1e-12, 1e-12, 4), jnp.array([0.1, 0.9, 0.9, 0.1])
    traces = []

    @eqx.filter_jit
    def limited(limit):
        traces.append(limit)
        return boxed_least_squares(res, solver, u0, None, 64, limit=limit)

    static = boxed_least_squares(res, solver, u0, None, steps)
    dynamic = limited(jnp.asarray(steps))
    assert int(dynamic.num_steps) == int(static.num_steps) >= steps  # both passes' steps
    assert dynamic.result == static.result == optx.RESULTS.nonlinear_max_steps_reached
    np.testing.assert_array_equal(np.asarray(dynamic.value), np.asarray(static.value))
    converged = limited(jnp.asarray(64))
    assert converged.result == optx.RESULTS.successful and int(converged.num_steps) < 64
    assert len(traces) == 1
