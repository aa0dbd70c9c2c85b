"""The cost module against numpy, and its worst-case handling of diverging candidates."""

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxheli.cost import fit_percent, metrics, paper_cost, pearson, rmse, tic


def _signals(seed, n=500, k=4):
    rng = np.random.default_rng(seed)
    meas = np.cumsum(rng.normal(size=(n, k)), axis=0)
    sim = meas + rng.normal(scale=3.0, size=(n, k))
    return sim, meas


def test_pearson_equals_numpy_corrcoef():
    sim, meas = _signals(0)
    rho = np.asarray(pearson(sim, meas))
    ref = [np.corrcoef(sim[:, i], meas[:, i])[0, 1] for i in range(4)]
    np.testing.assert_allclose(rho, ref, rtol=1e-12)
    np.testing.assert_allclose(float(paper_cost(sim, meas)), sum((1 - r) ** 2 for r in ref), rtol=1e-12)


def test_amplitude_metrics_equal_numpy():
    sim, meas = _signals(1)
    err = sim - meas
    np.testing.assert_allclose(rmse(sim, meas), np.sqrt((err**2).mean(0)), rtol=1e-12)
    ref_tic = np.sqrt((err**2).mean(0)) / (np.sqrt((sim**2).mean(0)) + np.sqrt((meas**2).mean(0)))
    np.testing.assert_allclose(tic(sim, meas), ref_tic, rtol=1e-12)
    ref_fit = 100 * (1 - np.linalg.norm(err, axis=0) / np.linalg.norm(meas - meas.mean(0), axis=0))
    np.testing.assert_allclose(fit_percent(sim, meas), ref_fit, rtol=1e-12)


def test_batched_equals_rows():
    sims = np.stack([_signals(s)[0] for s in range(5)])
    meas = _signals(0)[1]
    batched = np.asarray(paper_cost(sims, meas))
    rows = [float(paper_cost(s, meas)) for s in sims]
    np.testing.assert_allclose(batched, rows, rtol=1e-13)


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, 1e300])
def test_diverging_candidate_gets_worst_cost_not_nan(poison):
    sim, meas = _signals(2)
    bad = sim.copy()
    bad[300:, 1] = poison * np.linspace(1.0, 2.0, 200)  # 1e300 is finite, its squares are not
    rho = np.asarray(pearson(np.stack([sim, bad]), meas))
    assert np.isfinite(rho).all()
    assert rho[1, 1] == -1.0 and np.allclose(rho[1, [0, 2, 3]], rho[0, [0, 2, 3]])
    cost = np.asarray(paper_cost(np.stack([sim, bad]), meas))
    assert np.isfinite(cost).all() and cost[1] > cost[0]
    assert float(tic(bad, meas)[1]) == 1.0
    assert float(rmse(bad, meas)[1]) == np.inf
    assert float(fit_percent(bad, meas)[1]) == -np.inf


def test_all_nan_candidate_costs_4_per_channel_and_flat_is_worst():
    sim, meas = _signals(3)
    assert float(paper_cost(np.full_like(sim, np.nan), meas)) == 16.0
    assert float(paper_cost(np.full_like(sim, 2.5), meas)) == 16.0
    assert float(paper_cost(np.zeros_like(sim), meas)) == 16.0


def test_constant_measured_channel_raises():
    sim, meas = _signals(4)
    meas[:, 2] = 1.0
    with pytest.raises(Exception, match="measured channel is constant"):
        pearson(sim, meas).block_until_ready()


def test_shape_mismatch_raises():
    with pytest.raises(ValueError, match="meas.shape"):
        pearson(np.zeros((10, 3)), np.zeros((10, 4)))


def test_metrics_dict_has_every_channel():
    sim, meas = _signals(5)
    out = metrics(sim, meas, ("u", "v", "p", "q"))
    assert set(out) == {"pearson", "tic", "rmse", "fit_percent", "cost"}
    assert set(out["pearson"]) == {"u", "v", "p", "q"}


@settings(max_examples=25, deadline=None)
@given(scale=st.floats(1e-3, 1e3), offset=st.floats(-1e3, 1e3), seed=st.integers(0, 10_000))
def test_pearson_is_affine_invariant(scale, offset, seed):
    sim, meas = _signals(seed, n=200, k=2)
    a = np.asarray(pearson(sim, meas))
    b = np.asarray(pearson(scale * sim + offset, meas))
    np.testing.assert_allclose(a, b, atol=1e-9)
    assert (np.abs(a) <= 1).all()
    assert jnp.isfinite(paper_cost(sim, meas))
