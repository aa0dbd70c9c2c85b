"""Cramer-Rao standard errors against closed-form OLS, and identifiability on a synthetic flight."""

import json

import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.synth.excitation import multisine
from jaxheli.data.flight import FlightData
from jaxheli.model import PARAM_NAMES, PINNED, TABLE2
from jaxheli.optim.uncertainty import from_residuals, identifiable
from jaxheli.sim.simulate import simulate

OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
USED = ("Xu", "Lb")
UNUSED = ("Mu", "Zb", "Nrfb")


def _regression(n: int = 200, seed: int = 0):
    """``y = b0 x0 + b1 x1 + noise`` with (b0, b1) stored in theta[Xu], theta[Lb]; no other parameter enters."""
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 2)) + np.array([[0.5, -0.2]])
    y = X @ np.array([-0.3, 150.0]) + 0.1 * rng.standard_normal(n)
    idx = [PARAM_NAMES.index(p) for p in USED]

    def residuals(theta):
        return jnp.asarray(X) @ theta[jnp.asarray(idx)] - jnp.asarray(y)

    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    resid = X @ beta - y
    ols = np.sqrt(np.diag(resid @ resid / (n - 2) * np.linalg.inv(X.T @ X)))
    theta = TABLE2.copy()
    theta[idx] = beta
    return residuals, theta, ols, X


@pytest.mark.parametrize("free", [USED + UNUSED, None])
def test_stderr_matches_ols_and_flags_unused_parameters(free):
    residuals, theta, ols, X = _regression()
    unc = from_residuals(residuals, theta, free=free)
    idx = [PARAM_NAMES.index(p) for p in USED]
    np.testing.assert_allclose(unc.stderr[idx], ols, rtol=1e-8)
    corr = np.linalg.inv(X.T @ X)
    np.testing.assert_allclose(unc.correlation[idx[0], idx[1]], corr[0, 1] / np.sqrt(corr[0, 0] * corr[1, 1]),
                               rtol=1e-8)
    unused = [i for i, n in enumerate(PARAM_NAMES) if unc.free[i] and n not in USED]
    assert unc.rank == 2 and unc.dof == 198
    assert np.all(np.isinf(unc.stderr[unused])) and not unc.resolved[unused].any()
    assert unc.resolved[idx].all()
    fixed = [PARAM_NAMES.index(p) for p in PINNED]
    assert np.all(unc.stderr[fixed] == 0.0) and not unc.free[fixed].any()
    assert np.all(np.isfinite(unc.correlation))
    json.dumps(unc.to_dict())


def test_identifiability_on_a_flight_without_heave():
    t = np.arange(0.0, 15.01, 0.02)
    freqs = 0.1 * np.arange(1, 41)
    sticks = np.stack([multisine(t, freqs[i::4], 0.05, phases="random", seed=50 + i) for i in range(4)], 1)
    clean = np.asarray(simulate(TABLE2, FlightData(t, sticks, np.tile(np.arange(8.0), (t.size, 1)), OUTPUTS)))
    noisy = clean + 0.01 * clean.std(axis=0) * np.random.default_rng(5).standard_normal(clean.shape)
    flight = FlightData(t, sticks, noisy, OUTPUTS, source="synthetic multisine flight 5")
    # w is not fitted: the heave row (Za Zb Zw Zr Zcol) reaches no fitted output (Lw, Mw, Nw are pinned).
    # Nrfb and Kr enter only as their product: r_fb is unmeasured, so its scale is free.
    verdict = identifiable(flight, TABLE2, outputs=("u", "v", "p", "q", "phi", "theta", "r"), segment=1.0)
    unc = verdict.uncertainty
    unresolved = {n for i, n in enumerate(PARAM_NAMES) if unc.free[i] and not unc.resolved[i]}
    assert unresolved == {"Za", "Zb", "Zw", "Zr", "Zcol", "Nrfb", "Kr"}
    assert set(verdict.names) >= {"Lb", "Ma", "Xu", "Yv", "tf", "Alon", "Blat", "Dlat", "Nped", "ts"}
    assert all(verdict.reasons[p].startswith("fixed") for p in PINNED)
    assert verdict.reasons["Zw"].startswith("unresolved") and verdict.reasons["Lb"].startswith("identifiable")
    assert np.all(unc.relative[[PARAM_NAMES.index(p) for p in ("Lb", "Ma", "tf")]] < 0.01)
    json.dumps(verdict.to_dict())


def test_diverging_residuals_raise_or_leave_every_free_parameter_unresolved():
    def diverging(theta):
        return jnp.full(50, jnp.inf) * theta[0]

    with pytest.raises(ValueError, match="not finite"):
        from_residuals(diverging, TABLE2)
    unc = from_residuals(diverging, TABLE2, nonfinite="unresolved")
    free = ~np.isin(PARAM_NAMES, PINNED)
    assert np.all(np.isinf(unc.stderr[free])) and np.all(unc.stderr[~free] == 0) and not unc.resolved.any()


def test_a_nuisance_parameter_eliminated_by_projection_gives_the_full_fits_errors():
    """Variable projection: an intercept projected out of the residuals (``nuisance=1``) leaves the slopes' standard
    errors of the ordinary least-squares fit that estimates the intercept with them."""
    _, theta, _, X = _regression()
    rng = np.random.default_rng(1)
    y = X @ np.array([-0.3, 150.0]) + 4.0 + 0.1 * rng.standard_normal(X.shape[0])
    idx = [PARAM_NAMES.index(p) for p in USED]

    def projected(theta):
        e = jnp.asarray(X) @ theta[jnp.asarray(idx)] - jnp.asarray(y)
        return e - jnp.mean(e)

    full = np.column_stack([X, np.ones(X.shape[0])])
    beta, *_ = np.linalg.lstsq(full, y, rcond=None)
    resid = full @ beta - y
    ols = np.sqrt(np.diag(resid @ resid / (X.shape[0] - 3) * np.linalg.inv(full.T @ full)))[:2]
    theta = theta.copy()
    theta[idx] = beta[:2]
    unc = from_residuals(projected, theta, free=USED, nuisance=1)
    np.testing.assert_allclose(unc.stderr[idx], ols, rtol=1e-8)
    assert unc.dof == X.shape[0] - 3
