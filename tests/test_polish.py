"""Polishing a start with optimistix on the output error (the default), the paper's cost or the PEM objective:
lower, never higher."""

import numpy as np
import pytest

from jaxheli.cost import paper_cost
from jaxheli.synth.excitation import multisine
from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, PARAM_NAMES, TABLE2, UPPER, params_array
from jaxheli.bounds import Bounds
from jaxheli.optim.polish import polish
from jaxheli.sim.simulate import simulate

OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
STEPS = 40


@pytest.fixture(scope="module")
def flight() -> FlightData:
    """15 s of open-loop Table 2 response to multisines, 1 % noise (as in test_pem)."""
    t = np.arange(0.0, 15.01, 0.02)
    freqs = 0.1 * np.arange(1, 41)
    sticks = np.stack([multisine(t, freqs[i::4], 0.05, phases="random", seed=30 + i) for i in range(4)], 1)
    clean = np.asarray(simulate(TABLE2, FlightData(t, sticks, np.tile(np.arange(8.0), (t.size, 1)), OUTPUTS)))
    noisy = clean + 0.01 * clean.std(axis=0) * np.random.default_rng(3).standard_normal(clean.shape)
    return FlightData(t, sticks, noisy, OUTPUTS, source="synthetic multisine flight 3")


def _perturbed(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.where(Bounds().free_mask(), TABLE2 * (1 + rng.uniform(-0.2, 0.2, 40)), TABLE2)


def test_polish_lowers_the_paper_cost(flight):
    start = _perturbed(0)
    res = polish(start, flight, objective="pearson", max_steps=STEPS)
    assert res.cost < 0.5 * res.cost_start
    # The reported costs are the paper's cost of the same simulation (one open-loop run from rest).
    costs = [paper_cost(simulate(theta, flight), flight.outputs) for theta in (start, res.theta)]
    np.testing.assert_allclose(costs, [res.cost_start, res.cost], rtol=1e-9)
    assert np.all((res.theta >= LOWER) & (res.theta <= UPPER))
    assert res.settings["objective"] == "pearson" and res.n_steps <= STEPS


@pytest.mark.parametrize("start", ["truth", "perturbed", "unstable"])
def test_polish_never_raises_the_cost(flight, start):
    theta0 = {
        "truth": TABLE2,
        "perturbed": _perturbed(1),
        "unstable": params_array({"Xu": 1.0, "Zw": 1.0, "Nr": 10.0, "Krfb": 20.0}, TABLE2),
    }[start]
    res = polish(theta0, flight, objective="pearson", max_steps=STEPS)
    assert np.isfinite(res.cost) and res.cost <= res.cost_start
    if res.cost == res.cost_start:
        np.testing.assert_array_equal(res.theta, theta0)
    # the default, output error (its last round alone, the maximum-likelihood one): never raises its objective
    res = polish(theta0, flight, max_steps=STEPS, rounds=1)
    assert all(np.isfinite(r["rss"]) and r["rss"] <= r["rss_start"] for r in res.settings["rounds"])


def test_default_polish_identifies_the_amplitude(flight):
    """A start with the truth's shapes at half its control power: Pearson cannot see the gain, output error can."""
    start = TABLE2.copy()
    for name in ("Alat", "Alon", "Blat", "Blon", "Zcol", "Nped", "Ncol", "Clon", "Dlat"):
        start[PARAM_NAMES.index(name)] *= 0.5
    res = polish(start, flight, max_steps=STEPS)
    assert res.settings["objective"] == "output-error"
    y = np.asarray(simulate(res.theta, flight))
    gain = np.std(y, axis=0) / np.std(flight.outputs, axis=0)
    np.testing.assert_allclose(gain, 1.0, atol=0.05)


def test_polish_on_the_pem_objective(flight):
    start = _perturbed(2)
    res = polish(start, flight, objective="pem", segment=5.0, x0="measured", max_steps=STEPS)  # as in test_pem
    assert res.rss < 0.1 * res.rss_start and res.rss <= res.rss_start
    assert res.settings["objective"] == "pem"
    with pytest.raises(ValueError, match="objective"):
        polish(start, flight, objective="tic")


def test_several_starts_keep_the_best_on_every_objective(flight):
    """Two starts on the paper's objective: the answer is the better start's own polish (what iwo+freq+polish
    hands the polish with ``--polish-objective pearson``)."""
    starts = np.stack([_perturbed(0), _perturbed(1)])
    single = [polish(s, flight, objective="pearson", max_steps=STEPS) for s in starts]
    both = polish(starts, flight, objective="pearson", max_steps=STEPS)
    best = min(single, key=lambda res: res.cost)
    np.testing.assert_array_equal(both.theta, best.theta)
    assert both.cost == best.cost
