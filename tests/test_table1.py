"""The paper's Table 1 IWO column, reproduced from its Table 2 on flight C (ppr_data.mat)."""

import numpy as np

import jaxheli
from jaxheli.cost import pearson
from jaxheli.model import TABLE2
from jaxheli.sim.simulate import simulate

PRINTED = {"p": 0.9575, "q": 0.9089, "phi": 0.9084, "theta": 0.8722}


def test_table1_iwo_column_reproduced(shared_data):
    flight = jaxheli.load(shared_data / "trex550" / "ppr_data.mat")
    assert flight.n_samples == 861 and abs(flight.dt - 0.0081) < 1e-12
    chans = tuple(PRINTED)
    sim = simulate(TABLE2, flight, outputs=chans, hold="foh", g=9.8, x0="zero")
    rho = np.asarray(pearson(sim, flight.select(chans).outputs))
    for name, value in zip(chans, rho):
        # the printed values are the computed ones rounded to 4 decimals (phi: 0.90845 printed 0.9084)
        assert abs(value - PRINTED[name]) < 0.6e-4, (name, value)
    np.testing.assert_allclose(rho, [0.95747, 0.90894, 0.90845, 0.87223], atol=5e-6)


def test_zero_order_hold_on_flight_c_matches_scipy(shared_data):
    """ZOH on the same data against scipy's cont2discrete + dlsim + numpy corrcoef (independent path).

    data/README.md quotes 0.9554, 0.9038, 0.9093, 0.8682 for ZOH; scipy and jaxheli agree on
    0.95541, 0.90375, 0.90946, 0.86826 (phi differs from the quoted figure by 1.6e-4).
    """
    import scipy.signal as ss

    from jaxheli.model import build_ab

    flight = jaxheli.load(shared_data / "trex550" / "ppr_data.mat")
    chans = tuple(PRINTED)
    sim = np.asarray(simulate(TABLE2, flight, outputs=chans, hold="zoh", g=9.8))
    A, B = (np.asarray(m) for m in build_ab(TABLE2, g=9.8))
    C = np.eye(13)[[2, 3, 4, 5]]
    sysd = ss.cont2discrete((A, B, C, np.zeros((4, 4))), flight.dt, method="zoh")
    _, ref, _ = ss.dlsim(sysd, flight.inputs)
    np.testing.assert_allclose(sim, ref, rtol=1e-9, atol=1e-12)
    meas = flight.select(chans).outputs
    rho_ref = [np.corrcoef(ref[:, i], meas[:, i])[0, 1] for i in range(4)]
    np.testing.assert_allclose(np.asarray(pearson(sim, meas)), rho_ref, rtol=1e-9)
    np.testing.assert_allclose(rho_ref, [0.9554, 0.9038, 0.9093, 0.8682], atol=2e-4)
