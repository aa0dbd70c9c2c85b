"""population_cost: one jitted call over [P, 40], equal to simulate + numpy Pearson per candidate."""

import numpy as np

from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, TABLE2, UPPER
from jaxheli.sim.population import population_cost
from jaxheli.sim.simulate import simulate


def test_population_cost_matches_per_candidate_numpy():
    rng = np.random.default_rng(0)
    n, dt = 1200, 0.01
    t = np.arange(n) * dt
    u = 0.1 * np.sin(2 * np.pi * np.array([0.3, 0.5, 0.7, 0.9]) * t[:, None])
    truth = np.asarray(simulate(TABLE2, FlightData(t, u, np.zeros((n, 4)), ("p", "q", "phi", "theta"))))
    flight = FlightData(t, u, truth + 0.01 * rng.normal(size=truth.shape), ("p", "q", "phi", "theta"))
    thetas = LOWER + (UPPER - LOWER) * rng.uniform(size=(50, 40))
    thetas[0] = TABLE2
    thetas[1, 12] = 1e-9  # tau_f -> 0: a wildly stiff, diverging candidate
    cost = np.asarray(population_cost(thetas, flight))
    assert cost.shape == (50,) and np.isfinite(cost).all()
    sims = np.asarray(simulate(thetas, flight))
    for i in range(50):
        rho = []
        for c in range(4):
            s = sims[i, :, c]
            ok = np.isfinite(s).all() and np.ptp(s) > 0
            rho.append(np.corrcoef(s, flight.outputs[:, c])[0, 1] if ok else -1.0)
        np.testing.assert_allclose(cost[i], sum((1 - r) ** 2 for r in rho), rtol=1e-9, atol=1e-12)
    assert cost[0] < 1e-3
    assert cost[1] == 16.0 or cost[1] > cost[0]
