"""The consistency check's estimators against independent numpy/scipy references: the sub-sample lag
(np.interp-shifted signals, scipy's scalar minimiser of the residual sum of squares, 95 % coverage of its
2-sigma interval), the Newey-West covariance (the textbook lag loop) and the velocity bias and drift
(np.polyfit)."""

import numpy as np
import pytest
import scipy.optimize
import scipy.signal

from jaxheli import piloted_flight
from jaxheli.gap._lag import fit_lag
from jaxheli.gap._regress import hac_lstsq
from jaxheli.gap.consistency import MAX_TRAVEL_M, check

DT, N, TRUE_LAG = 0.01, 1500, 0.0237


def _pair(seed):
    """Band-limited signal ``x`` and ``target(t) = 1.3 x(t + TRUE_LAG) + 0.2`` plus AR(1) noise."""
    rng = np.random.default_rng(seed)
    t = DT * np.arange(N)
    x = scipy.signal.sosfiltfilt(scipy.signal.butter(4, 2.0, fs=1 / DT, output="sos"), rng.normal(size=N))
    x /= x.std()
    noise = scipy.signal.lfilter([1.0], [1.0, -0.8], rng.normal(scale=0.1, size=N))
    return t, 1.3 * np.interp(t + TRUE_LAG, t, x) + 0.2 + noise, x


def _fit(t, target, x):
    return fit_lag(t, target, x, [np.ones_like(t)], max_lag=0.1, edge=0.2, bandwidth=10)


def test_lag_matches_the_least_squares_minimiser():
    """Gauss-Newton lands on the minimum of the residual sum of squares over the np.interp-shifted signal."""
    t, target, x = _pair(0)
    lag = _fit(t, target, x)
    keep = (t > t[0] + 0.3) & (t < t[-1] - 0.3)

    def rss(tau):
        X = np.stack([np.interp(t + tau, t, x), np.ones_like(t)], axis=1)[keep]
        return np.sum((target[keep] - X @ np.linalg.lstsq(X, target[keep], rcond=None)[0]) ** 2)

    ref = scipy.optimize.minimize_scalar(rss, bounds=(-0.1, 0.1), method="bounded", options={"xatol": 1e-7}).x
    assert lag.converged and abs(lag.tau - ref) < 0.1 * lag.sigma
    assert lag.fit.beta[0] == pytest.approx(1.3, rel=0.02)


def test_lag_sigma_is_calibrated():
    """Over 200 noise draws the 2-sigma interval holds the true sub-sample lag about 95 % of the time."""
    fits = [_fit(*_pair(seed)) for seed in range(200)]
    taus = np.array([f.tau for f in fits])
    sigmas = np.array([f.sigma for f in fits])
    assert all(f.converged for f in fits)
    coverage = np.mean(np.abs(taus - TRUE_LAG) < 2 * sigmas)
    assert 0.88 <= coverage <= 0.99, coverage
    assert abs(taus.mean() - TRUE_LAG) < 3 * taus.std() / np.sqrt(taus.size)
    assert np.median(sigmas) == pytest.approx(taus.std(), rel=0.3)


def test_newey_west_matches_the_lag_loop():
    rng = np.random.default_rng(1)
    X = np.stack([np.ones(800), rng.normal(size=800).cumsum(), rng.normal(size=800)], axis=1)
    y = X @ [0.5, 0.01, 2.0] + scipy.signal.lfilter([1.0], [1.0, -0.9], rng.normal(size=800))
    fit = hac_lstsq(y, X, min_bandwidth=30)
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    score = X * (y - X @ beta)[:, None]
    meat = score.T @ score
    for k in range(1, fit.bandwidth + 1):
        gamma = score[k:].T @ score[:-k]
        meat += (1 - k / (fit.bandwidth + 1)) * (gamma + gamma.T)
    bread = np.linalg.inv(X.T @ X)
    np.testing.assert_allclose(fit.beta, beta, rtol=1e-10)
    np.testing.assert_allclose(fit.cov, bread @ meat @ bread, rtol=1e-8, atol=1e-14)


@pytest.fixture(scope="module")
def clean():
    return piloted_flight(duration=30.0, seed=3)


def _velocity(findings, kind, vel):
    (hit,) = [f for f in findings if f.kind == kind and f.channels == (vel,)]
    return hit


def test_velocity_bias_and_drift_match_polyfit_and_flag_implausible_travel(clean):
    """Mean and drift equal np.polyfit's line; a 0.5 m/s bias over 30 s (15 m) is flagged, the clean hover not."""
    u = clean.output("u")
    biased = clean.replace(outputs=clean.outputs + 0.5 * (np.array(clean.output_names) == "u"))
    keep = (clean.time > clean.time[0] + 0.5) & (clean.time < clean.time[-1] - 0.5)
    tc = clean.time - 0.5 * (clean.time[0] + clean.time[-1])
    drift, mean = np.polyfit(tc[keep], u[keep], 1)
    findings, flagged = check(clean), check(biased)
    assert _velocity(findings, "velocity_bias", "u").estimate == pytest.approx(mean, abs=1e-12)
    assert _velocity(findings, "velocity_drift", "u").estimate == pytest.approx(drift, abs=1e-12)
    assert _velocity(flagged, "velocity_bias", "u").estimate == pytest.approx(mean + 0.5, abs=1e-12)
    for vel in ("u", "v", "w"):
        assert not _velocity(findings, "velocity_bias", vel).significant
        assert not _velocity(findings, "velocity_drift", vel).significant
    hit = _velocity(flagged, "velocity_bias", "u")
    assert hit.significant and abs(hit.estimate) * clean.duration > MAX_TRAVEL_M
    assert not any(f.significant for f in flagged if f.kind in ("velocity_drift", "velocity_lag"))
    assert not _velocity(check(biased, max_travel=100.0), "velocity_bias", "u").significant
