"""Fitting a low-passed record at its bandwidth's step: the step chosen from the record's provenance, identify's
``fit_dt`` (the stages on the resampled record, scores and standard errors on the record itself), its refusals."""

import numpy as np
import pytest

from jaxheli import identify, make_problem, piloted_flight
from jaxheli.identify import scores
from jaxheli.data.preprocess import bandwidth_step, lowpass, resample
from jaxheli.model import PARAM_NAMES, TABLE2
from jaxheli.optim.uncertainty import standard_errors


def identify_stderr(params, problem):
    """The Cramer-Rao standard errors identify reports, by name."""
    return dict(zip(PARAM_NAMES, map(float, standard_errors(problem, params, nonfinite="unresolved").stderr)))
from jaxheli.synth.excitation import Excitation


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
    start = np.where(np.asarray(TABLE2) != 0.0, 1.1 * np.asarray(TABLE2), 0.0)
    coarse = identify(low_passed, method="pem", fit_dt="auto", start=start)
    full = identify(low_passed, method="pem", fit_dt="full", start=start)
    assert coarse.settings["fit_dt"] == [pytest.approx(0.04)] and full.settings["fit_dt"] is None
    assert coarse.convergence["converged"] and full.convergence["converged"]
    own_step = make_problem(low_passed).variant(segment=5.0, x0="measured")  # PEM's training scores: 5-s runs
    assert scores(coarse.params, own_step)["fit_percent"] == coarse.train["fit_percent"]
    assert not np.array_equal(coarse.params, full.params)  # the stages saw the resampled record
    assert coarse.stderr == identify_stderr(coarse.params, own_step)


def test_fit_dt_refusals(low_passed):
    with pytest.raises(ValueError, match="finer than"):
        identify(low_passed, method="pem", fit_dt=0.005)
    with pytest.raises(ValueError, match="'auto', 'full'"):
        identify(low_passed, method="pem", fit_dt="coarse")
    with pytest.raises(ValueError, match="needs flights"):
        identify(make_problem(low_passed), method="pem", fit_dt="auto")
