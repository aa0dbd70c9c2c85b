"""Velocity bias judged by what the record integrates to: the noise level of a velocity channel, the
uncertainty of its integral (white noise integrated, a bias random walk), a known bias flagged through a
pilot's slow wandering, a bias-free record of the same length not flagged, and flight A's sinking w."""

import math

import numpy as np
import pytest

from jaxheli import load, piloted_flight
from jaxheli.gap._regress import hac_lstsq
from jaxheli.gap.consistency import MAX_TRAVEL_M, check
from jaxheli.gap.detectors.signals import EDGE_S, interior
from jaxheli.gap.detectors.travel import TRAVEL_SIGMA, VELOCITY_WALK, noise_level

SIGMA_W = 0.05
"""White noise of the synthetic w records, m/s."""


@pytest.fixture(scope="module")
def clean():
    return piloted_flight(duration=30.0, seed=3)


def _bias(findings, vel):
    (hit,) = [f for f in findings if f.kind == "velocity_bias" and f.channels == (vel,)]
    return hit


def _with_w(flight, w):
    out = flight.outputs.copy()
    out[:, flight.output_names.index("w")] = w
    return flight.replace(outputs=out)


def _wander(t):
    """A pilot's slow vertical wandering, m/s: 1 m/s at a 12 s period."""
    return np.sin(2 * np.pi * t / 12.0)


def test_noise_level_recovers_white_noise_under_motion():
    """Motion below the cutoff is not noise; white noise is found at its level, 2 % here."""
    rng = np.random.default_rng(1)
    dt, n = 0.01, 6000
    t = dt * np.arange(n)
    motion = 1.5 * np.sin(2 * np.pi * 0.2 * t) + 0.7 * np.sin(2 * np.pi * 0.7 * t + 1.0)
    keep = interior(t, EDGE_S)
    for sigma in (0.01, 0.05, 0.2):
        level = noise_level(motion + sigma * rng.normal(size=n), 1.0 / dt, 2.0, keep)
        assert level == pytest.approx(sigma, rel=0.05)


def test_white_noise_integrates_to_sigma_dt_sqrt_n():
    """The white part of the integral's sigma against Monte Carlo: 2000 records of N samples."""
    rng = np.random.default_rng(2)
    dt, n = 0.01, 2900
    t = dt * np.arange(n)
    integrals = [np.trapezoid(SIGMA_W * rng.normal(size=n), t) for _ in range(2000)]
    assert np.std(integrals) == pytest.approx(SIGMA_W * dt * math.sqrt(n), rel=0.05)


def test_known_bias_flagged_through_wandering_bias_free_not(clean):
    """w = 0.6 m/s + wandering + white noise integrates to a known 17 m: flagged with the integral's sigma,
    which a stationary-process error of the mean (Newey-West, +-T se) would have hidden; the same record
    without the bias integrates to under a metre and is not flagged."""
    rng = np.random.default_rng(3)
    t = clean.time
    keep = interior(t, EDGE_S)
    t0, t1 = t[keep][0], t[keep][-1]
    noise = SIGMA_W * rng.normal(size=clean.n_samples)
    wander_integral = 12.0 / (2 * np.pi) * (np.cos(2 * np.pi * t0 / 12.0) - np.cos(2 * np.pi * t1 / 12.0))
    sigma = math.hypot(SIGMA_W * clean.dt * math.sqrt(keep.sum()), VELOCITY_WALK * math.sqrt((t1 - t0) ** 3 / 3))
    for bias, flagged in ((0.6, True), (0.0, False)):
        w = bias + _wander(t) + noise
        known = bias * (t1 - t0) + wander_integral
        found = _bias(check(_with_w(clean, w)), "w")
        assert abs(found.estimate * (t1 - t0) - known) < 3 * SIGMA_W * clean.dt * math.sqrt(keep.sum()) + 0.02
        assert found.uncertainty * (t1 - t0) == pytest.approx(sigma, rel=0.05)
        assert found.significant == flagged, found.message
        assert (abs(known) - MAX_TRAVEL_M > TRAVEL_SIGMA * sigma) == flagged
        if flagged:
            tc = t - 0.5 * (t[0] + t[-1])
            stationary = hac_lstsq(w[keep], np.stack([np.ones_like(tc), tc], axis=1)[keep], min_bandwidth=50)
            assert abs(known) - MAX_TRAVEL_M < TRAVEL_SIGMA * stationary.se[0] * (t1 - t0)
            assert "w is biased" in found.message


def test_flight_a_w_bias_flagged(shared_data):
    """Flight A's airborne segment starts just after take-off and ends just after landing (data README: rows
    4136-12725 of a session airborne from about row 4000 to 12500), yet its w integrates to a 36 m sink:
    flagged, 8 sigma beyond the plausible 10 m; u and v end within it."""
    flight = load(shared_data / "trex550" / "Data_graphready.mat")
    findings = check(flight)
    w = _bias(findings, "w")
    assert w.significant and "exceeded by 8.1 sigma: w is biased" in w.message
    assert "integrates to 35.7 +- 3.2 m over the 67.3 s checked" in w.message
    assert w.estimate == pytest.approx(0.531, abs=5e-4) and w.uncertainty * 67.3 == pytest.approx(3.2, abs=0.05)
    assert not _bias(findings, "u").significant and not _bias(findings, "v").significant
