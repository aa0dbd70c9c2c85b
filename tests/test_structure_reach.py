"""The structure's reach (:mod:`jaxheli.benchmark.structure_reach`): a hover model fitted alone to a noise-free
training flight takes up a change of the hover model itself within the sensor noise on the held-out flight, and
leaves an effect no hover model has (a sensor bias that settles and wanders) above it."""

import numpy as np
import pytest

from jaxheli.benchmark import truth as ts
from jaxheli.benchmark.structure_reach import structure_reach
from jaxheli.bounds import Bounds, physical_box
from jaxheli.model import PARAM_NAMES, TABLE2

DURATION, DT = 20.0, 0.05
SIGMA = np.array([ts.NOISE[c] for c in ts.OUTPUTS])


def _flights(theta: np.ndarray, effects: ts.Effects) -> tuple[ts.Record, ts.Record]:
    common = dict(duration=DURATION, dt=DT, noise=SIGMA, outputs=ts.OUTPUTS)
    return (ts.fly(theta, effects, style="doublets", seed=4, **common),
            ts.fly(theta, effects, style=ts.VALIDATE_STYLE, seed=5, **common))


@pytest.fixture(scope="module")
def truth() -> np.ndarray:
    return ts.wide_truth(TABLE2, np.random.default_rng(3))


def test_without_an_effect_the_truths_own_hover_model_leaves_nothing(truth):
    reach = structure_reach(truth, *_flights(truth, ts.Effects()), SIGMA, ts.OUTPUTS)
    assert reach.size < 0.05 and reach.beyond < 0.05 and reach.reachable, reach


def test_another_hover_model_is_within_the_structures_reach(truth):
    other = truth.copy()
    for name, factor in (("Xu", 1.6), ("Yv", 1.6), ("Lb", 0.7), ("Ma", 0.7)):
        other[PARAM_NAMES.index(name)] *= factor
    box = physical_box(Bounds())
    assert np.all((other >= box.lower) & (other <= box.upper))
    reach = structure_reach(truth, *_flights(other, ts.Effects()), SIGMA, ts.OUTPUTS)
    assert reach.size > 2.0, reach
    assert reach.beyond < 0.5 and reach.reachable, reach


def test_a_settling_wandering_roll_bias_lies_beyond_it(truth):
    bias = ts.BiasDrift("phi", start=0.02, settle=0.06, settle_tau=6.0, sigma=0.02, tau=4.0)
    reach = structure_reach(truth, *_flights(truth, ts.Effects(bias=bias)), SIGMA, ts.OUTPUTS)
    assert reach.size > 2.0 and reach.beyond > 2.0 and not reach.reachable, reach
