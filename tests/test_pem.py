"""Prediction-error minimisation on synthetic flights of the Table 2 truth (known answers)."""

import json

import numpy as np
import pytest

from jaxheli.cost import pearson
from jaxheli.synth.excitation import multisine
from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, PARAM_NAMES, PINNED, TABLE2, UPPER, params_array
from jaxheli.bounds import Bounds

_BOX = Bounds()
clip_unit, free_mask, from_unit, midpoint, to_unit = (Bounds.clip_unit, _BOX.free_mask, _BOX.from_unit,
                                                      _BOX.midpoint, _BOX.to_unit)
from jaxheli.optim.pem import pem
from jaxheli.sim.simulate import simulate

OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
WELL_IDENTIFIED = ("Lb", "Ma", "Xu", "Yv", "tf", "Alon", "Blat", "Dlat", "Nped", "Zcol", "ts")
"""Relative Cramer-Rao standard error below 0.5 % on this flight (see test_uncertainty)."""
SEGMENT, STEPS = 5.0, 40
"""Predictor restarts every 5 s (3 segments); every solve in these tests uses these settings or the paper's
simulation, so the suite compiles one solver per objective."""


def synthetic_flight(seed: int, duration: float = 15.0, dt: float = 0.02, noise: float = 0.01) -> FlightData:
    """Open-loop Table 2 response to random-phase multisines (0.1-4 Hz, interleaved per axis, peak 0.05),
    from rest, plus white noise of ``noise`` times each channel's standard deviation."""
    t = np.arange(0.0, duration + dt / 2, dt)
    freqs = 0.1 * np.arange(1, 41)
    sticks = np.stack([multisine(t, freqs[i::4], 0.05, phases="random", seed=10 * seed + i) for i in range(4)], 1)
    clean = np.asarray(simulate(TABLE2, FlightData(t, sticks, np.tile(np.arange(8.0), (t.size, 1)), OUTPUTS)))
    rng = np.random.default_rng(seed)
    outputs = clean + noise * clean.std(axis=0) * rng.standard_normal(clean.shape)
    return FlightData(t, sticks, outputs, OUTPUTS, source=f"synthetic multisine flight {seed}")


def perturbed(seed: int = 0) -> np.ndarray:
    """Table 2 with every free parameter scaled by 1 +- (10..20 %), random signs."""
    rng = np.random.default_rng(seed)
    factor = 1 + rng.uniform(0.1, 0.2, 40) * rng.choice([-1.0, 1.0], 40)
    return np.where(free_mask(), TABLE2 * factor, TABLE2)


@pytest.fixture(scope="module")
def fitted():
    flight = synthetic_flight(1)
    return flight, pem(flight, start=perturbed(), segment=SEGMENT, max_steps=STEPS)


def test_pem_recovers_well_identified_parameters(fitted):
    _, res = fitted
    assert res.rss < 0.01 * res.rss_start and res.cost < res.cost_start
    assert res.free == tuple(n for n in PARAM_NAMES if n not in PINNED)
    err = {n: abs(res.theta[i] / TABLE2[i] - 1) for i, n in enumerate(PARAM_NAMES) if n in WELL_IDENTIFIED}
    assert max(err.values()) < 0.03, err
    assert np.all((res.theta >= LOWER) & (res.theta <= UPPER))
    json.dumps(res.to_dict())


def test_pem_validates_on_a_second_flight(fitted):
    _, res = fitted
    other = synthetic_flight(2)
    rho_truth, rho_fit = (np.asarray(pearson(simulate(th, other), other.outputs)) for th in (TABLE2, res.theta))
    np.testing.assert_allclose(rho_fit, rho_truth, atol=0.01)
    assert rho_truth.min() > 0.99


def test_pem_beats_the_truth_on_its_own_data(fitted):
    flight, res = fitted
    at_truth = pem(flight, start=TABLE2, segment=SEGMENT, max_steps=STEPS)
    # From the truth the solver only fits noise: both answers reach the same noise floor.
    assert at_truth.rss == pytest.approx(res.rss, rel=0.02)
    assert at_truth.rss <= at_truth.rss_start


def test_pem_survives_a_diverging_start():
    flight = synthetic_flight(1)
    wild = params_array({"Xu": 1.0, "Yv": 1.0, "Zw": 1.0, "Nr": 10.0, "Krfb": 20.0}, TABLE2)
    res = pem(flight, start=wild, segment=SEGMENT, max_steps=STEPS)
    assert res.rss_start > 1e12  # the start diverges: a real pole near +26 1/s, e^130 over one segment
    values = [res.cost_start, res.cost, res.rss_start, res.rss]
    assert np.all(np.isfinite(values)) and np.all(np.isfinite(res.theta))
    # progress in PEM's own objective; the Pearson cost is not it, and from this start where LM lands in it
    # depends on the CPU's rounding (13.7 from 10.3 on an AVX-512 host, lower on others)
    assert res.rss < 1e-2 * res.rss_start
    assert np.all((res.theta >= LOWER) & (res.theta <= UPPER))
    assert res.result in ("successful", "nonlinear_max_steps_reached")


def test_box_coordinates_and_free_masks():
    theta = np.where(free_mask(), np.random.default_rng(3).uniform(LOWER, UPPER), LOWER)
    np.testing.assert_allclose(from_unit(to_unit(theta)), theta, atol=1e-12)
    np.testing.assert_allclose(to_unit(midpoint())[free_mask()], 0.5)
    np.testing.assert_array_equal(clip_unit(np.array([-0.5, 0.0, 0.3, 1.0, 2.0])), [0.0, 0.0, 0.3, 1.0, 1.0])
    assert free_mask(["Lb", "Ma"]).sum() == 2 and free_mask().sum() == 40 - len(PINNED)
    with pytest.raises(ValueError, match="pinned"):
        free_mask(["Lw"])
    with pytest.raises(ValueError, match="unknown"):
        free_mask(["Lbb"])
