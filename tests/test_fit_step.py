"""Fitting a low-passed record at its bandwidth's step: the step chosen from the record's provenance, identify's
``fit_dt`` (the stages on the resampled record, scores and standard errors on the record itself), its refusals, and
the input hold chosen by the record (first-order for low-passed sticks) and read back wherever a result is scored."""

import json

import numpy as np
import pytest

from jaxheli import evaluate, identify, make_problem, piloted_flight, verify
from jaxheli.identify import scores
from jaxheli.data.preprocess import bandwidth_step, input_cutoff, lowpass, resample
from jaxheli.model import PARAM_NAMES, TABLE2
from jaxheli.optim.uncertainty import standard_errors
from jaxheli.stages import PEM
from jaxheli.synth.excitation import Excitation

START = np.where(np.asarray(TABLE2) != 0.0, 1.1 * np.asarray(TABLE2), 0.0)
"""PEM's start in these tests: 10 % off the truth."""
QUICK = [PEM(start=START, steps=2)]
"""A two-step PEM, where only the settings a fit records matter (its step-limit warning is expected)."""
SHORT_FIT = pytest.mark.filterwarnings("ignore:identify. the best trial's least-squares fit stopped")


def identify_stderr(params, problem):
    """The Cramer-Rao standard errors identify reports, by name."""
    return dict(zip(PARAM_NAMES, map(float, standard_errors(problem, params, nonfinite="unresolved").stderr)))


@pytest.fixture(scope="module")
def low_passed():
    """A 30-s synthetic flight at 0.01 s, inputs and outputs low-passed at 3 Hz (as flight A is prepared)."""
    flight = piloted_flight(duration=30.0, dt=0.01, excitation=Excitation("mixed", band=(0.2, 2.5)), seed=4)
    return lowpass(flight, 3.0)


def test_the_step_is_the_largest_whole_multiple_within_an_eighth_of_the_cutoff_period(low_passed):
    assert bandwidth_step(low_passed) == pytest.approx(0.04)  # floor(1 / (8 x 3 Hz x 0.01 s)) = 4 steps
    assert bandwidth_step(low_passed, samples_per_period=5) == pytest.approx(0.06)
    assert bandwidth_step(lowpass(low_passed, 2.0)) == pytest.approx(0.06)  # the lowest cut-off applied
    assert bandwidth_step(resample(low_passed, 0.05)) is None  # already coarser than the step: its own step
    bare = piloted_flight(duration=30.0, dt=0.01, seed=4)
    assert bandwidth_step(bare) is None  # not low-passed
    assert bandwidth_step(lowpass(bare, 3.0, include_inputs=False)) is None  # sticks not filtered: would alias


def test_identify_fits_at_the_step_and_scores_at_the_records_own(low_passed):
    """PEM from a start 10 % off the truth, at the bandwidth step (a quarter of the samples): the stages fit the
    resampled record, and the scores and standard errors reported are those of the answer on the record itself."""
    coarse = identify(low_passed, method="pem", start=START)  # fit_dt="auto": the default
    full = identify(low_passed, method="pem", fit_dt="full", start=START)
    assert coarse.settings["fit_dt"] == [pytest.approx(0.04)] and full.settings["fit_dt"] is None
    assert coarse.settings["hold"] == full.settings["hold"] == "foh"  # the sticks were low-passed
    assert coarse.convergence["converged"] and full.convergence["converged"]
    own_step = make_problem(low_passed, hold="foh").variant(segment=5.0, x0="measured")  # PEM's scores: 5-s runs
    assert scores(coarse.params, own_step)["fit_percent"] == coarse.train["fit_percent"]
    assert not np.array_equal(coarse.params, full.params)  # the stages saw the resampled record
    assert coarse.stderr == identify_stderr(coarse.params, own_step)


def test_fit_dt_refusals(low_passed):
    with pytest.raises(ValueError, match="finer than"):
        identify(low_passed, method="pem", fit_dt=0.005)
    with pytest.raises(ValueError, match="'auto', 'full'"):
        identify(low_passed, method="pem", fit_dt="coarse")
    with pytest.raises(ValueError, match="needs flights"):
        identify(make_problem(low_passed), method="pem", fit_dt=0.04)


@SHORT_FIT
def test_the_hold_follows_the_sticks_filtering_and_a_given_hold_stands(low_passed):
    """``hold="auto"`` (the default) is first-order only where every training flight's sticks were low-passed; a
    Problem keeps its own hold and its own step."""
    bare = piloted_flight(duration=30.0, dt=0.01, excitation=Excitation("mixed", band=(0.2, 2.5)), seed=4)
    outputs_only = lowpass(bare, 3.0, include_inputs=False)
    assert input_cutoff(low_passed) == 3.0 and input_cutoff(outputs_only) is None and input_cutoff(bare) is None
    fit = {name: identify(f, QUICK)
           for name, f in [("bare", bare), ("outputs only", outputs_only), ("both", [low_passed, bare])]}
    assert {name: r.settings["hold"] for name, r in fit.items()} == {"bare": "zoh", "outputs only": "zoh",
                                                                      "both": "zoh"}
    assert fit["bare"].settings["fit_dt"] is None and fit["outputs only"].settings["fit_dt"] is None
    given = identify(low_passed, QUICK, hold="zoh")
    assert given.settings["hold"] == "zoh" and given.settings["fit_dt"] == [pytest.approx(0.04)]
    problem = identify(make_problem(low_passed), QUICK)
    assert problem.settings["hold"] == "zoh" and problem.settings["fit_dt"] is None


@SHORT_FIT
def test_verify_and_evaluate_score_a_result_with_the_hold_it_was_fitted_with(low_passed, tmp_path):
    """A result's recorded hold is the default wherever it is scored again; bare parameters keep zero-order."""
    fit = identify(low_passed, QUICK)
    path = tmp_path / "result.json"
    path.write_text(json.dumps(fit.to_json(), default=str))  # as jaxheli.save_result writes it
    assert fit.settings["hold"] == "foh"
    recorded, first, zero = (verify(m, low_passed, **h) for m, h in [(path, {}), (fit.params, {"hold": "foh"}),
                                                                       (fit.params, {})])
    assert recorded.pooled == first.pooled and recorded.pooled != zero.pooled
    assert evaluate(str(path), low_passed) == evaluate(fit.params, low_passed, hold="foh")
    assert evaluate(str(path), low_passed)["simulation"]["hold"] == "foh"
    assert evaluate(fit.params, low_passed)["simulation"]["hold"] == "zoh"
