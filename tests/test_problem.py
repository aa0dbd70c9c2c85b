"""One Problem per record: settings round-trip, variants need no flight, and a user's box reaches every engine."""

import json

import numpy as np
import pytest

import jaxheli
from jaxheli.bounds import Bounds
from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, PARAM_NAMES, TABLE2, UPPER
from jaxheli.optim.polish import polish
from jaxheli.optim.uncertainty import standard_errors
from jaxheli.problem import Problem, Settings, as_problem, make_problem
from jaxheli.sim.simulate import make_simulator
from jaxheli.synth.piloted import piloted_flight

OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")


@pytest.fixture(scope="module")
def flight() -> FlightData:
    return piloted_flight(duration=30.0, dt=0.05, seed=3)


@pytest.fixture(scope="module")
def box() -> tuple[np.ndarray, np.ndarray]:
    """A user's box: 20 % around Table 2, Lb pinned away from its Table-2 value, Lw (pinned by the authors) freed."""
    lower = np.minimum(0.8 * TABLE2, 1.2 * TABLE2)
    upper = np.maximum(0.8 * TABLE2, 1.2 * TABLE2)
    lower, upper = np.where(lower == upper, LOWER, lower), np.where(lower == upper, UPPER, upper)
    i = PARAM_NAMES.index("Lb")
    lower[i] = upper[i] = 150.0
    j = PARAM_NAMES.index("Lw")
    lower[j], upper[j] = -0.05, 0.05
    return lower, upper


def test_settings_round_trip_through_json():
    s = Settings(outputs=("p", "q"), segment=2.0, x0="measured", precision="float32")
    back = Settings.from_dict(json.loads(json.dumps(s.to_dict())))
    assert back == s and hash(back) == hash(s)
    with pytest.raises(ValueError, match="unknown fields"):
        Settings.from_dict({"segmnt": 1.0})


def test_problem_holds_what_the_engines_need(flight):
    p = make_problem(flight, segment=1.0)
    assert p.outputs == OUTPUTS and str(p.source) == flight.source
    np.testing.assert_array_equal(p.target, flight.outputs)
    np.testing.assert_allclose(p.scale, flight.outputs.std(axis=0))
    direct = make_simulator(flight, outputs=OUTPUTS, segment=1.0)
    np.testing.assert_array_equal(p.sim(TABLE2), direct(TABLE2))
    # a variant is the simulator that make_simulator builds from the flight under those settings
    v = p.variant(segment=0.5, x0="measured", hold="foh", simulator="scan")
    ref = make_simulator(flight, outputs=OUTPUTS, segment=0.5, x0="measured", hold="foh", method="scan")
    np.testing.assert_allclose(v.sim(TABLE2), ref(TABLE2), rtol=1e-12, atol=1e-12)
    assert v.sim.describe() == ref.describe()
    with pytest.raises(ValueError, match="cannot change"):
        p.variant(outputs=("p",))
    assert as_problem(p) is p and isinstance(as_problem(flight), Problem)


def test_user_bounds_reach_every_engine(flight, box):
    lower, upper = box
    bounds = Bounds(lower, upper)
    problem = make_problem(flight, lower=lower, upper=upper)
    i_lb, i_lw = PARAM_NAMES.index("Lb"), PARAM_NAMES.index("Lw")

    # PEM and the polish stay in the user's box, pinned axes at their pinned value
    start = np.clip(TABLE2 * 1.5, lower, upper)
    fit = jaxheli.pem(problem.variant(segment=1.0, x0="measured"), start=start, max_steps=5)
    polished = polish(start, problem, max_steps=5, rounds=1)
    for theta in (fit.theta, polished.theta):
        assert bounds.contains(theta) and theta[i_lb] == 150.0
    assert "Lw" in fit.free and "Lb" not in fit.free  # the authors' box pins Lw and frees Lb

    # the population engine searches the same box
    result = jaxheli.identify(flight, method="iwo", iterations=2, lower=lower, upper=upper, progress=False)
    assert bounds.contains(result.trial_params).all() and result.params[i_lb] == 150.0

    # standard errors: Lb is not estimated (0), Lw is (finite, positive)
    theta = TABLE2.copy()
    theta[i_lb] = 150.0
    unc = standard_errors(problem.variant(segment=1.0), theta)
    assert unc.stderr[i_lb] == 0.0 and unc.free[i_lw] and 0.0 < unc.stderr[i_lw] < np.inf
    # and the authors' box would refuse Lw as a free parameter
    with pytest.raises(ValueError, match="pinned"):
        Bounds().free_mask(["Lw"])
