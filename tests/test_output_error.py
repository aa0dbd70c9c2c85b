"""The output-error fit (the default polish): restarts chosen from the model's instability, every run from its
least-squares state, and recovery of a known truth within its Cramer-Rao standard errors."""

import importlib

import numpy as np
import pytest

from jaxheli.bounds import Bounds
from jaxheli.identify import scores
from jaxheli.model import R50_SI, TABLE2, build_ab, params_array
from jaxheli.optim.output_error import (GROWTH, LADDER, RACE_STEPS, SEGMENTS, in_runs, output_error,
                                       output_error_problem, restart_interval)
from jaxheli.optim.pem import residuals
from jaxheli.optim.polish import polish
from jaxheli.optim.uncertainty import cramer_rao_coverage, standard_errors
from jaxheli.problem import make_problem
from jaxheli.sim.shooting import SHORTEST_RUN_S, run_states
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
    assert chosen.settings.segment is None and chosen.settings.x0 == "estimated"  # Table 2 grows < GROWTH x in 20 s
    np.testing.assert_allclose(np.asarray(run_states(chosen.sim, TABLE2))[0, [0, 2]], [0.3, 0.05], atol=0.02)
    # the start is absorbed: the errors are those of the unshifted flight
    plain = output_error_problem(make_problem(flight), TABLE2)
    errors = [np.sum((np.asarray(p.sim(TABLE2)) - np.asarray(p.target)) ** 2) for p in (chosen, plain)]
    assert errors[0] == pytest.approx(errors[1], rel=0.01)


def test_an_unstable_truth_leaves_only_the_sensor_noise():
    """Mettler's R-50 doubles its phugoid in 2.3 s; started from measured states every second its errors carry the
    sensors' noise amplified, started from estimated states over the whole record they are the noise."""
    excitation = Excitation("mixed", amplitude=(0.1,) * 4, unit=0.3, band=(0.3, 4.0))
    data = piloted_flight(R50_SI, duration=20.0, dt=0.02, excitation=excitation, seed=5)
    noise = np.array([data.metadata["noise"][c] for c in make_problem(data).outputs])
    expected = make_problem(data).target.shape[0] * np.sum((noise / np.asarray(make_problem(data).scale)) ** 2)
    estimated = make_problem(data).variant(x0="estimated")
    rss = float(np.sum(np.asarray(residuals(estimated, R50_SI)) ** 2))
    measured = make_problem(data).variant(x0="measured", segment=1.0)
    assert abs(rss / expected - 1.0) < 0.05
    assert float(np.sum(np.asarray(residuals(measured, R50_SI)) ** 2)) > 2.0 * rss


def test_output_error_recovers_the_truth_from_a_perturbed_start(flight):
    rng = np.random.default_rng(0)
    start = np.where(Bounds().free_mask(), TABLE2 * (1 + rng.uniform(-0.15, 0.15, 40)), TABLE2)
    problem = make_problem(flight)
    res = polish(start, problem)  # the default objective
    rounds = res.settings["rounds"]
    assert res.settings["objective"] == "output-error" and rounds[0]["segment_s"] == [LADDER[0]]
    assert rounds[1]["segment_s"] == [None]  # the ladder's next run, 20 s, is the whole record
    truth_rss, start_rss = (float(np.sum(np.asarray(residuals(output_error_problem(problem, TABLE2), th)) ** 2))
                            for th in (TABLE2, start))
    assert res.rss < 1.01 * truth_rss < 0.7 * start_rss  # down to the noise floor
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


def test_several_starts_race_and_the_leader_alone_finishes_the_round(flight, monkeypatch):
    """Two starts, one near the truth and one far: each takes RACE_STEPS steps, the round goes on from the one of
    least sum of squares alone, and the answer is never worse than either after the race. The race's legs and the
    leader's rest run one compiled solver (one step bound, though 20 and 80 steps alone would take 64 and 128)."""
    rng = np.random.default_rng(1)
    near, far = (np.where(Bounds().free_mask(), TABLE2 * (1 + rng.uniform(-f, f, 40)), TABLE2) for f in (0.1, 0.4))
    problem = make_problem(flight)
    pem = importlib.import_module("jaxheli.optim.pem")  # the module (jaxheli.optim.pem is also the function's name)
    bounds, solve = [], pem._solve
    monkeypatch.setattr(pem, "_solve", lambda *args: bounds.append(args[3]) or solve(*args))
    res = output_error(problem, np.stack([far, near]), rounds=1, max_steps=RACE_STEPS + 80)
    monkeypatch.undo()
    assert len(bounds) == 3 and len(set(bounds)) == 1
    (round_,) = res.settings["rounds"]
    far_rss, near_rss = round_["starts_rss"]
    assert near_rss < far_rss and res.rss <= near_rss
    np.testing.assert_array_equal(res.theta_start, near)
    alone = output_error(problem, near, rounds=1, max_steps=RACE_STEPS)  # the race's leg of the near start
    assert near_rss == pytest.approx(alone.rss, rel=1e-9)
    assert res.n_steps <= RACE_STEPS + 80  # the far start's race leg is not counted


def test_runs_of_every_length_share_one_compiled_solver(flight, monkeypatch):
    """The run length of estimated runs is a run-time value of the simulator: fits in runs of 1 s, 2 s and one run
    over the record trace (and compile) the solver once, and still simulate different runs."""
    pem = importlib.import_module("jaxheli.optim.pem")
    window = flight.replace(time=flight.time[:731], inputs=flight.inputs[:731], outputs=flight.outputs[:731])
    problem = make_problem(window)  # a length no other test compiles for
    traced, residual = [], pem._residual
    monkeypatch.setattr(pem, "_residual", lambda v, boxed: traced.append(1) or residual(v, boxed))
    fits = []
    for segment in (1.0, 2.0, None):
        fits.append(pem.fit(in_runs(problem, segment), TABLE2, "pem", "lm", 3, None, 1e-8, 1e-8))
        if segment == 1.0:
            first = len(traced)
    assert first > 0 and len(traced) == first
    assert len({round(f.rss_start, 6) for f in fits}) == 3


def test_every_run_length_the_fit_uses_is_within_the_compiled_bound():
    """Restart intervals and ladder caps no shorter than the runs that bound the compiled run count, so no round
    compiles a solver of its own."""
    assert min(SEGMENTS + LADDER) >= SHORTEST_RUN_S
