"""The simulator against scipy (cont2discrete + dlsim, lsim), row-by-row batching and segment restarts."""

import numpy as np
import pytest
import scipy.signal as ss

from jaxheli.data.flight import FlightData
from jaxheli.model import G_SI, LOWER, R50_G, R50_HOVER, TABLE2, UPPER, build_ab, params_array
from jaxheli.sim.simulate import make_simulator, simulate

ALL = ("u", "v", "p", "q", "phi", "theta", "a", "b", "w", "r")
STABLE = params_array({"Zw": -0.8, "Xu": -0.3, "Yv": -0.9}, base=TABLE2)
CASES = {
    "stable": (STABLE, G_SI),
    "table2_unstable": (TABLE2, G_SI),
    "r50_unstable": (R50_HOVER, R50_G),
}


def _flight(n=2000, dt=0.01, seed=0, outputs=ALL):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    # smooth random sticks: a few sines per axis
    u = sum(0.05 * rng.normal(size=4) * np.sin(2 * np.pi * f * t[:, None] + rng.uniform(0, 6, 4)) for f in (0.2, 0.7, 1.9))
    y = rng.normal(size=(n, len(outputs)))
    return FlightData(t, u, y, outputs, source="test")


def _rel(a, b):
    return np.max(np.abs(np.asarray(a) - b)) / np.max(np.abs(b))


def test_stable_case_is_stable_and_unstable_cases_are_not():
    assert np.linalg.eigvals(np.asarray(build_ab(STABLE)[0])).real.max() < 0
    for name in ("table2_unstable", "r50_unstable"):
        theta, g = CASES[name]
        assert np.linalg.eigvals(np.asarray(build_ab(theta, g)[0])).real.max() > 0


@pytest.mark.parametrize("case", sorted(CASES))
def test_zoh_matches_scipy_dlsim(case):
    theta, g = CASES[case]
    f = _flight()
    A, B = (np.asarray(m) for m in build_ab(theta, g))
    C = np.eye(13)[[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]]
    Ad, Bd, Cd, Dd, _ = ss.cont2discrete((A, B, C, np.zeros((10, 4))), f.dt, method="zoh")
    _, ref, _ = ss.dlsim((Ad, Bd, Cd, Dd, f.dt), f.inputs, x0=np.zeros(13))
    y = simulate(theta, f, g=g, hold="zoh")
    assert _rel(y, ref) < 1e-9


@pytest.mark.parametrize("case", sorted(CASES))
def test_foh_matches_scipy_lsim(case):
    theta, g = CASES[case]
    f = _flight(n=1500)
    A, B = (np.asarray(m) for m in build_ab(theta, g))
    C = np.eye(13)[:10]
    _, ref, _ = ss.lsim((A, B, C, np.zeros((10, 4))), f.inputs, f.time, interp=True)
    y = simulate(theta, f, g=g, hold="foh")
    assert _rel(y, ref) < 1e-9


def test_population_equals_single_rows():
    f = _flight(n=800)
    rng = np.random.default_rng(3)
    thetas = LOWER + (UPPER - LOWER) * rng.uniform(size=(7, 40))
    thetas[0] = TABLE2
    pop = np.asarray(simulate(thetas, f, outputs=("p", "q", "phi", "theta"), segment=1.0))
    assert pop.shape == (7, 800, 4)
    for i in range(7):
        one = np.asarray(simulate(thetas[i], f, outputs=("p", "q", "phi", "theta"), segment=1.0))
        np.testing.assert_allclose(pop[i], one, rtol=1e-12, atol=1e-300)


def _numpy_segments(theta, f, seg, reset, x0):
    """Independent reference: a plain loop with scipy's discretisation and explicit restarts."""
    A, B = (np.asarray(m) for m in build_ab(theta))
    Ad, Bd, *_ = ss.cont2discrete((A, B, np.eye(13), np.zeros((13, 4))), f.dt, method="zoh")
    idx = [("u", "v", "p", "q", "phi", "theta", "a", "b", "w", "r").index(c) for c in f.output_names]
    real = [i for i, c in zip(idx, f.output_names) if c not in ("a", "b")]
    real_cols = [j for j, c in enumerate(f.output_names) if c not in ("a", "b")]
    x = x0.copy()
    out = [x[idx]]
    for k in range(1, f.n_samples):
        x = Ad @ x + Bd @ f.inputs[k - 1]
        out.append(x[idx])
        if k % seg == 0:
            if reset == "zero":
                x = np.zeros(13)
            x[real] = f.outputs[k, real_cols]
    return np.array(out)


@pytest.mark.parametrize("reset", ["carry", "zero"])
@pytest.mark.parametrize("x0", ["zero", "measured"])
def test_segment_restarts_match_reference_loop(reset, x0):
    f = _flight(n=600, outputs=("u", "v", "p", "q", "phi", "theta", "a", "w"))
    start = np.zeros(13)
    if x0 == "measured":
        start[[0, 1, 2, 3, 4, 5, 8]] = f.outputs[0, [0, 1, 2, 3, 4, 5, 7]]
    ref = _numpy_segments(R50_HOVER, f, 50, reset, start)
    y = simulate(R50_HOVER, f, segment=0.5, reset=reset, x0=x0)
    assert _rel(y, ref) < 1e-10


def test_segments_bound_an_unstable_model():
    f = _flight(n=8000)
    long_run = np.asarray(simulate(R50_HOVER, f, g=R50_G))
    seg = np.asarray(simulate(R50_HOVER, f, g=R50_G, segment=2.0))
    assert np.abs(long_run).max() > 1e3 * np.abs(seg).max()


def test_simulator_describes_its_mode():
    f = _flight(n=100)
    assert "single open-loop run" in make_simulator(f).describe()["mode"]
    d = make_simulator(f, segment=0.2).describe()
    assert "multiple shooting" in d["mode"] and d["segment_s"] == pytest.approx(0.2)


def test_bad_options_raise():
    f = _flight(n=100, outputs=("p", "q"))
    with pytest.raises(ValueError, match="not in the flight"):
        make_simulator(f, outputs=("phi",))
    with pytest.raises(ValueError, match="hold"):
        make_simulator(f, hold="cubic")
    with pytest.raises(ValueError, match="segment"):
        make_simulator(f, segment=0.001)
    with pytest.raises(ValueError, match="x0"):
        make_simulator(f, x0=np.zeros(12))


def test_estimated_initial_state_recovers_a_known_one():
    from jaxheli.sim.initial_state import estimate_x0

    f = _flight(n=400)
    x0 = np.zeros(13)
    x0[[0, 1, 2, 3, 4, 5, 8, 9]] = [0.5, -0.3, 0.1, -0.05, 0.08, -0.04, 0.2, 0.03]
    y = np.asarray(simulate(STABLE, f, x0=x0, outputs=("u", "v", "p", "q", "phi", "theta", "w", "r")))
    data = FlightData(f.time, f.inputs, y, ("u", "v", "p", "q", "phi", "theta", "w", "r"))
    est = estimate_x0(STABLE, data)
    np.testing.assert_allclose(est[[0, 1, 2, 3, 4, 5, 8, 9]], x0[[0, 1, 2, 3, 4, 5, 8, 9]], atol=1e-6)
    refit = np.asarray(simulate(STABLE, data, x0=est))
    np.testing.assert_allclose(refit, y, atol=1e-8)
