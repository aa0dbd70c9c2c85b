"""The output-error fit (the default polish): restarts chosen from the model's instability, the initial state
estimated, and recovery of a known truth within its Cramer-Rao standard errors."""

import numpy as np
import pytest

from jaxheli.bounds import Bounds
from jaxheli.identify import scores
from jaxheli.model import TABLE2, build_ab, params_array
from jaxheli.optim.output_error import GROWTH, SEGMENTS, output_error_problem, restart_interval
from jaxheli.optim.pem import fit, residuals
from jaxheli.optim.polish import polish
from jaxheli.optim.uncertainty import cramer_rao_coverage, standard_errors
from jaxheli.problem import make_problem
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import piloted_flight


def _max_real_pole(theta):
    return np.max(np.linalg.eigvals(np.asarray(build_ab(theta)[0])).real)


@pytest.fixture(scope="module")
def flight():
    """20 s of the piloted Table 2 flight at 50 Hz (3-2-1-1s then sweeps), default sensor noise."""
    excitation = Excitation("mixed", amplitude=(0.2,) * 4, unit=0.3, band=(0.3, 4.0))
    return piloted_flight(TABLE2, duration=20.0, dt=0.02, excitation=excitation, seed=3)


def test_restart_interval_follows_the_fastest_unstable_mode():
    rate = _max_real_pole(TABLE2)  # ~ +0.05 1/s
    horizon = np.log(GROWTH) / rate
    assert restart_interval(TABLE2, 9.81, 0.5 * horizon) is None  # grows < GROWTH x over the record: one run
    assert restart_interval(TABLE2, 9.81, 10 * horizon) == max(s for s in SEGMENTS if s <= horizon)
    fast = params_array({"Xu": 1.0}, TABLE2)  # u' = +u - g theta ...: a pole near +1 1/s
    expected = [s for s in SEGMENTS if s <= np.log(GROWTH) / _max_real_pole(fast)]
    assert restart_interval(fast, 9.81, 80.0) == (expected[-1] if expected else SEGMENTS[0])
    assert restart_interval(np.where(Bounds().free_mask(), np.nan, TABLE2), 9.81, 80.0) == SEGMENTS[0]


def test_output_error_problem_estimates_the_initial_state(flight):
    start = np.zeros(13)
    start[[0, 2]] = (0.3, 0.05)  # u = 0.3 m/s, p = 0.05 rad/s at t = 0
    shifted = flight.replace(outputs=np.asarray(flight.outputs)
                             + np.asarray(make_problem(flight).sim.replace_x0(start)(TABLE2))
                             - np.asarray(make_problem(flight).sim(TABLE2)))
    chosen = output_error_problem(make_problem(shifted), TABLE2)
    assert chosen.settings.segment is None  # Table 2 grows < 10x in 20 s
    np.testing.assert_allclose(np.asarray(chosen.sim.x0)[[0, 2]], [0.3, 0.05], atol=0.02)


def test_output_error_recovers_the_truth_from_a_perturbed_start(flight):
    rng = np.random.default_rng(0)
    start = np.where(Bounds().free_mask(), TABLE2 * (1 + rng.uniform(-0.15, 0.15, 40)), TABLE2)
    problem = make_problem(flight)
    res = polish(start, problem, max_steps=30)  # the default objective
    assert res.settings["objective"] == "output-error" and len(res.settings["rounds"]) == 3
    truth_rss = float(np.sum(np.asarray(residuals(output_error_problem(problem, TABLE2), TABLE2)) ** 2))
    assert res.rss < 1.01 * truth_rss < 0.7 * res.rss_start  # down to the noise floor
    # validation on a second flight: fit % within 3 points of the truth's own on every channel
    validate = make_problem(piloted_flight(TABLE2, duration=10.0, dt=0.02, excitation=Excitation("3211", unit=0.3),
                                           seed=4))
    fitted, truth = scores(res.theta, validate), scores(TABLE2, validate)
    for c in problem.outputs:
        assert fitted["fit_percent"][c] > truth["fit_percent"][c] - 3.0, c
    # the truth lies within 3 Cramer-Rao standard errors for >= 90 % of the identifiable parameters
    unc = standard_errors(output_error_problem(problem, res.theta), res.theta)
    coverage = cramer_rao_coverage(unc, TABLE2)
    assert len(coverage["identifiable"]) >= 15 and coverage["fraction"] >= 0.9, coverage


def test_cramer_rao_coverage_counts_identifiable_parameters_within_k_errors():
    class Unc:  # the fields cramer_rao_coverage reads
        theta = np.array([1.0, 2.0, 3.0, 4.0] + [0.0] * 36)
        stderr = np.array([0.1, 0.1, 10.0, np.inf] + [0.0] * 36)
        relative = np.array([0.1, 0.05, 10 / 3, np.inf] + [0.0] * 36)
        resolved = np.array([True, True, True, False] + [False] * 36)

    truth = np.array([1.25, 2.35, 3.0, 4.0] + [0.0] * 36)
    cov = cramer_rao_coverage(Unc(), truth)
    assert cov["identifiable"] == ["Xu", "Xa"] and cov["within"] == ["Xu"] and cov["fraction"] == 0.5
    np.testing.assert_allclose([cov["z"]["Xu"], cov["z"]["Xa"]], [-2.5, -3.5])


def test_rounds_holding_the_initial_state_share_the_fitting_rounds_program(flight):
    """A round that holds the initial state runs in the program compiled with the initial-state unknowns (a traced
    flag, zero Jacobian columns, no step on them), and finds what the fit without those unknowns finds, to 1e-6."""
    rng = np.random.default_rng(1)
    start = np.where(Bounds().free_mask(), TABLE2 * (1 + rng.uniform(-0.1, 0.1, 40)), TABLE2)
    chosen = output_error_problem(make_problem(flight), start)
    plain = fit(chosen, start, "pem", "lm", 8, None, 1e-8, 1e-8)
    shared = fit(chosen, start, "pem", "lm", 8, None, 1e-8, 1e-8, with_x0=True)
    assert plain.x0 is None and plain.rss < plain.rss_start
    np.testing.assert_allclose(shared.theta, plain.theta, rtol=1e-6)
    np.testing.assert_allclose(shared.rss, plain.rss, rtol=1e-6)
    np.testing.assert_array_equal(shared.x0[0], np.asarray(chosen.sim.x0))  # held where it was estimated
    assert shared.n_steps == plain.n_steps
