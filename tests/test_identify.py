"""identify() end to end on piloted synthetic flights with a known truth, and the identify/evaluate CLI."""

import json

import numpy as np
import pytest

from jaxheli.benchmark.throughput import bench_flight
from jaxheli.cli import main
from jaxheli.synth.excitation import Excitation
from jaxheli.identify import identify, intervals95, validation_block
from jaxheli.io import save_npz
from jaxheli.model import LOWER, PARAM_NAMES, TABLE2, UPPER
from jaxheli.synth.piloted import piloted_flight
from jaxheli.stages import PEM

FREE = ("Xu", "Yv", "Lb", "Ma", "Zw", "Nr", "Alon", "Blat")
"""Parameters the population test frees (rotor-to-body moments, dampings, control power)."""
CHANNELS = ("u", "v", "p", "q", "phi", "theta", "w", "r")


@pytest.fixture(scope="module")
def flights():
    train = piloted_flight(duration=40.0, dt=0.02, seed=1)  # 3-2-1-1s then sweeps on every axis
    validate = piloted_flight(duration=20.0, dt=0.02, excitation=Excitation("3211", unit=0.3), seed=2)
    return train, validate


def _box(frac):
    lower, upper = TABLE2.copy(), TABLE2.copy()
    for name in FREE:
        i = PARAM_NAMES.index(name)
        span = frac * abs(TABLE2[i])
        lower[i], upper[i] = max(LOWER[i], TABLE2[i] - span), min(UPPER[i], TABLE2[i] + span)
    return lower, upper


def _truth_validation(validate):
    return validation_block(TABLE2, validate, CHANNELS)


def test_iwo_polish_matches_truth_on_validation(flights):
    train, validate = flights
    lower, upper = _box(0.3)
    result = identify(train, method="iwo+polish", validate=validate, iterations=25, trials=2, seed=0,
                      lower=lower, upper=upper, polish_steps=40, progress=False)
    truth = _truth_validation(validate)
    # the default polish fits the output error, so amplitudes too: fit % within 3 points of the truth's own
    for c in CHANNELS:
        assert abs(result.validate["pearson"][c] - truth["pearson"][c]) < 0.01, c
        assert result.validate["fit_percent"][c] > truth["fit_percent"][c] - 3.0, c
    assert result.polish["objective"] == "output-error"
    assert result.polish["objective_after"] <= result.polish["objective_before"]
    assert result.intervals95 is not None and result.history.shape == (2, 25)
    # the flight knows its truth: scored beside, and within 3 Cramer-Rao standard errors of the result
    assert result.truth["validate"]["fit_percent"] == pytest.approx(truth["fit_percent"], abs=1e-9)
    assert result.truth["cramer_rao"]["fraction"] >= 0.9, result.truth["cramer_rao"]
    assert result.train["cost"] < 0.05


def test_pem_matches_truth_on_validation(flights):
    train, validate = flights
    rng = np.random.default_rng(0)
    start = TABLE2 * (1 + 0.1 * rng.uniform(-1, 1, 40))
    result = identify(train, method="pem", validate=validate, start=start, pem_segment=5.0)
    truth = _truth_validation(validate)
    for c in CHANNELS:
        assert abs(result.validate["pearson"][c] - truth["pearson"][c]) < 0.01, c
    assert result.convergence["converged"] and result.to_json()["convergence"] == result.convergence


def test_a_pem_base_that_stops_at_its_step_limit_says_so(flights):
    train, _ = flights
    with pytest.warns(UserWarning, match="stopped before converging"):
        result = identify(train, method=[PEM(steps=2)])
    assert not result.convergence["converged"] and result.convergence["trials"][0]["steps"] == 2
    assert "convergence" not in identify(train, method="iwo", iterations=2, progress=False).to_json()


def test_intervals_are_t_intervals_of_the_trial_mean():
    trials = np.random.default_rng(0).normal(size=(10, 40))
    iv = intervals95(trials)
    half = 2.2621571627409915 * trials.std(0, ddof=1) / np.sqrt(10)
    np.testing.assert_allclose(iv["Xu"], [trials[:, 0].mean() - half[0], trials[:, 0].mean() + half[0]])
    assert intervals95(trials[:1]) is None


def test_identify_and_evaluate_cli_write_the_documented_files(flights, tmp_path, capsys):
    train, validate = flights
    save_npz(train, tmp_path / "train.npz")
    save_npz(validate, tmp_path / "validate.npz")
    out = tmp_path / "run"
    rc = main(["identify", "--method", "iwo", "--train", str(tmp_path / "train.npz"), "--validate",
               str(tmp_path / "validate.npz"), "--iterations", "3", "--trials", "2", "--checkpoint-every", "1",
               "--out", str(out)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "TIC (<= 0.3)" in printed and "J_rms (<= 2)" in printed  # the validation flight verified in 5-s runs
    assert "modes of A" in printed and "parameters on a bound of the search box" in printed
    progress = json.loads((out / "checkpoint.eqx.json").read_text())
    assert (progress["iteration"], progress["chunk"]) == (3, 1)
    content = json.loads((out / "result.json").read_text())
    for key in ("method", "seed", "settings", "parameters", "intervals95", "stderr", "train", "validate", "modes",
                "at_bounds"):
        assert key in content
    assert set(content["parameters"]) == set(PARAM_NAMES)
    for block in ("train", "validate"):
        assert set(content[block]["pearson"]) == set(CHANNELS) and "tic" in content[block] and "cost" in content[block]
    for name in ("result.npz", "verification_train.png", "verification_validate.png", "convergence.png"):
        assert (out / name).is_file(), name
    rc = main(["evaluate", "--model", str(out / "result.json"), "--data", str(tmp_path / "validate.npz"),
               "--out", str(tmp_path / "eval.json")])
    assert rc == 0
    ev = json.loads((tmp_path / "eval.json").read_text())
    assert ev["pearson"] == pytest.approx(content["validate"]["pearson"], abs=1e-9)


def test_default_method_polishes_iwo_alone_when_no_pair_is_coherent():
    """On a record too short for any coherent frequency response the default method says so and goes on (the real
    flight A, low-passed at 3 Hz, is such a record)."""
    flight = bench_flight(300)  # 3 s of multi-sines
    with pytest.warns(UserWarning, match="frequency fit skipped"):
        result = identify(flight, iterations=2, polish_steps=2, polish_rounds=1, progress=False)
    assert result.method == "iwo+freq+polish" and result.frequency is None
    assert "no (input, output) pair" in result.settings["frequency_skipped"]
    assert result.polish["rounds"][0].get("starts_rss") is None  # IWO's best alone
    # one round, recorded on the scale of the objective reported for the polish (the convergence plot's panel)
    assert result.polish["objective_rounds"] == [[pytest.approx(result.polish["objective_before"]),
                                                  pytest.approx(result.polish["objective_after"])]]


@pytest.mark.filterwarnings("ignore:identify. the best trial.s least-squares fit stopped:UserWarning")  # not under test here
def test_a_problem_with_conflicting_flight_settings_is_refused():
    """A Problem's settings replace identify's flight settings: one given otherwise is a one-line error naming
    it; the same value as the problem's, or the default, is no conflict."""
    from jaxheli.problem import make_problem

    flight = bench_flight(200)
    problem = make_problem(flight, segment=2.0, outputs=("p", "q"))
    with pytest.raises(ValueError, match=r"segment=1\.0 \(the problem has 2\.0\).*hold='foh'") as info:
        identify(problem, method="pem", segment=1.0, hold="foh")
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="upper="):
        identify(problem, method="pem", upper=UPPER + 1.0)
    result = identify(problem, method="pem", segment=2.0, outputs=["p", "q"])
    assert tuple(result.settings["outputs"]) == ("p", "q") and result.settings["segment"] == 2.0


@pytest.mark.filterwarnings("ignore:identify. the best trial.s least-squares fit stopped:UserWarning")  # not under test here
def test_the_result_records_the_box_it_searched_and_flags_its_bounds_against_it():
    """A box other than the authors' is recorded in the result's settings, and a parameter on that box's bound is
    flagged against it (not against the authors' box)."""
    from jaxheli.results import result_at_bounds

    lower, upper = LOWER.copy(), UPPER.copy()
    i = PARAM_NAMES.index("Lb")
    upper[i] = 125.0  # below Table 2's Lb (133.6), which the roll response fixes: the fit ends on this bound
    result = identify(bench_flight(200), method="pem", lower=lower, upper=upper)
    assert result.settings["upper"] == upper.tolist() and result.settings["lower"] == lower.tolist()
    flagged = {a.name: a for a in result_at_bounds(result)}
    assert flagged["Lb"].side == "upper" and flagged["Lb"].bound == 125.0


def test_the_polish_rounds_are_recorded_on_the_scale_of_its_objective():
    """``objective_rounds``: the paper's cost for a Pearson polish, else sums of squares per sample, one pair per
    output-error round and one for the other objectives."""
    from types import SimpleNamespace

    from jaxheli.stages._polish import objective_rounds

    res = SimpleNamespace(cost_start=2.0, cost=1.0, rss_start=40.0, rss=10.0, settings={"objective": "pem"})
    assert objective_rounds(res, "pearson", 10) == [[2.0, 1.0]]
    assert objective_rounds(res, "pem", 10) == [[4.0, 1.0]]
    res.settings = {"rounds": [{"rss_start": 40.0, "rss": 20.0}, {"rss_start": 30.0, "rss": 10.0}]}
    assert objective_rounds(res, "output-error", 10) == [[4.0, 2.0], [3.0, 1.0]]
