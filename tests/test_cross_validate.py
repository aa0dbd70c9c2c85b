"""Leave-one-window-out cross-validation of the output-error polish: windows, the held-out measure against a
numpy/scipy reference, the choice, and the whole-flight fit that follows it."""

import numpy as np
import pytest

from jaxheli.identify import identify
from jaxheli.model import TABLE2, params_array
from jaxheli.optim.cross_validate import RUN_S, _heldout_error, cross_validate, windows
from jaxheli.optim.output_error import in_runs, output_error
from jaxheli.problem import Records, Settings, make_problem
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import piloted_flight

from numpy_reference import estimated_runs

OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
FINALS = (5.0, 20.0, None)  # 20 s and None both become one window (20 s) here


@pytest.fixture(scope="module")
def flight():
    """40 s of the piloted Table 2 flight at 20 Hz (3-2-1-1s), default sensor noise, plus 3 samples left over."""
    return piloted_flight(TABLE2, duration=40.15, dt=0.05, excitation=Excitation("3211", unit=0.3), seed=5)


@pytest.fixture(scope="module")
def start():
    return params_array({"Xu": -0.02, "Lb": 130.0, "Ma": 75.0, "tf": 0.07}, TABLE2)


def test_windows_are_equal_contiguous_and_checked(flight):
    parts = windows(flight, 4)
    size = flight.n_samples // 4
    assert [p.n_samples for p in parts] == [size] * 4
    np.testing.assert_array_equal(np.concatenate([p.time for p in parts]), flight.time[:4 * size])
    np.testing.assert_array_equal(parts[2].outputs, flight.outputs[2 * size:3 * size])
    with pytest.raises(ValueError, match="cross-validation needs >= 2 windows"):
        windows(flight, 5)  # 8 s windows: shorter than two scoring runs
    for count in (1, 0, -2):
        with pytest.raises(ValueError, match="cross-validation needs >= 2 windows"):
            windows(flight, count)


def test_the_choice_is_the_least_held_out_error_and_its_folds_match_a_numpy_reference(flight, start):
    settings = Settings(outputs=OUTPUTS)
    found = cross_validate(flight, settings, start, 2, rounds=2, max_steps=6, finals=FINALS)
    span = (flight.n_samples // 2 - 1) * flight.dt  # "as long as the data allow": one window
    labels = {5.0: "5 s", span: f"{span:.4g} s"}
    assert list(found.heldout) == list(labels.values()) and all(len(v) == 2 for v in found.heldout.values())
    errors = {(f, r): found.heldout[labels[f]][r - 1] for f in labels for r in (1, 2)}
    assert (found.final, found.rounds) == min(errors, key=errors.get)
    for label, folds in found.folds.items():
        np.testing.assert_allclose(found.heldout[label], np.mean(folds, axis=0))
    # fold 1 (window 1 left out) refitted with the chosen run length, stopped at the chosen round, then scored on
    # the left-out window by plain numpy: 5-s runs from their least-squares states, normalised squared errors
    parts = windows(flight, 2)
    train = Records((make_problem(parts[0], settings),))
    theta = output_error(train, start, rounds=2, max_steps=6, final=found.final, stop=found.rounds).theta
    meas = parts[1].select(OUTPUTS).outputs
    sim, _ = estimated_runs(theta, parts[1], RUN_S, OUTPUTS)
    reference = np.mean(((sim - meas) / meas.std(axis=0)) ** 2)
    assert found.folds[labels[found.final]][1][found.rounds - 1] == pytest.approx(reference, rel=1e-6)
    assert "chosen over 2 windows" in found.describe() and found.to_json()["final_s"] == found.final


def test_stop_ends_the_schedule_early_without_changing_it(flight, start):
    problem = make_problem(flight, Settings(outputs=OUTPUTS))
    full = output_error(problem, start, rounds=3, max_steps=5)
    early = output_error(problem, start, rounds=3, max_steps=5, stop=1)
    (first,) = early.settings["rounds"]
    assert first["segment_s"] == full.settings["rounds"][0]["segment_s"] == [5.0]  # the ladder's first cap
    np.testing.assert_allclose(early.theta, full.settings["rounds"][0]["theta"], rtol=1e-12)
    capped = output_error(problem, start, rounds=2, max_steps=5, final=5.0)
    assert [r["segment_s"] for r in capped.settings["rounds"]] == [[5.0], [5.0]]  # no cap below 5 s: every run 5 s


@pytest.mark.parametrize("method, options, several, message", [
    ("iwo", {}, False, "method 'iwo' does not use 'cv_windows'"),
    ("iwo+polish", {"polish_objective": "pearson"}, False, "cv_windows need the output-error objective"),
    ("iwo+polish", {}, True, "cv_windows needs one training flight"),
])
def test_identify_refuses_cross_validation_it_cannot_do(flight, method, options, several, message):
    data = [flight, flight] if several else flight
    with pytest.raises(ValueError, match=message):
        identify(data, method=method, cv_windows=4, iterations=1, progress=False, **options)


def test_identify_refuses_windows_too_short_before_any_search(flight):
    with pytest.raises(ValueError, match="5 windows of 40.2 s leave 8 s each; cross-validation needs >= 2 windows of >= 10 s"):
        identify(flight, method="iwo+polish", cv_windows=5, iterations=10**6, progress=False)


def test_identify_polishes_with_the_schedule_the_cross_validation_chose(flight):
    res = identify(flight, method="iwo+polish", iterations=2, cv_windows=2, polish_rounds=2, polish_steps=3,
                   outputs=OUTPUTS, progress=False)
    chosen = res.polish["cross_validation"]
    assert chosen["windows"] == 2 and res.settings["cv_windows"] == 2
    assert list(chosen["heldout"]) == ["5 s", f"{(flight.n_samples // 2 - 1) * flight.dt:.4g} s"]
    rounds = res.polish["rounds"]
    assert len(rounds) <= chosen["rounds"]  # stopped where the cross-validation said
    assert all(s <= chosen["final_s"] + 1e-9 for s in rounds[-1]["segment_s"])  # runs capped at the chosen length


def test_a_diverging_model_scores_the_worst_held_out_error_not_nan(flight):
    window = in_runs(make_problem(windows(flight, 2)[0], Settings(outputs=OUTPUTS)), RUN_S)
    sane = float(_heldout_error(window, np.asarray(TABLE2)))
    for bad in (np.full(40, np.nan), params_array({"Xu": 1e6}, TABLE2)):
        worst = float(_heldout_error(window, bad))
        assert np.isfinite(worst) and worst > 1e6 * sane
