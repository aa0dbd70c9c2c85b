"""The blocked kernel against the plain scan: outputs and costs, every hold, restart and x0 mode; NaN safety."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.sim.blocked import choose_block
from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, R50_G, R50_HOVER, TABLE2, UPPER, params_array
from jaxheli.cost import paper_cost
from jaxheli.sim.population import population_cost, simulator_cost
from jaxheli.sim.simulate import _run, make_simulator

CHANNELS = ("u", "v", "p", "q", "phi", "theta", "a", "w")
STABLE = params_array({"Zw": -0.8, "Xu": -0.3, "Yv": -0.9}, base=TABLE2)
X0_GIVEN = np.linspace(-0.5, 0.5, 13)


def _flight(n, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    u = sum(0.05 * rng.normal(size=4) * np.sin(2 * np.pi * f * t[:, None] + rng.uniform(0, 6, 4)) for f in (0.2, 0.7, 1.9))
    y = np.cumsum(rng.normal(size=(n, len(CHANNELS))), axis=0) * 0.01
    return FlightData(t, u, y, CHANNELS, source="test")


def _pair(flight, **options):
    return make_simulator(flight, method="scan", **options), make_simulator(flight, method="blocked", **options)


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300))


# (samples, options): N - 1 a multiple of the block or not, every hold / restart / x0 combination once
SETTINGS = [
    (803, dict(hold="zoh", x0="zero")),  # one long run, tail of 2 samples after blocks of 16
    (801, dict(hold="foh", segment=0.4, reset="carry", x0="measured")),  # blocks of 20, no tail
    (811, dict(hold="zoh", segment=0.5, reset="carry", x0=X0_GIVEN)),  # blocks of 10 (divide 50)
    (805, dict(hold="foh", segment=0.08, reset="zero", x0="zero")),  # segment shorter than a block: L = 8
    (1203, dict(hold="foh", x0=X0_GIVEN, g=R50_G)),  # Mettler's R-50, unstable, one long run
]


@pytest.mark.parametrize("n, options", SETTINGS)
def test_blocked_equals_scan(n, options):
    """Outputs to 1e-9 of their largest value, costs to 1e-6 relative, stable and unstable models."""
    f = _flight(n)
    scan, blocked = _pair(f, **options)
    assert blocked.method == "blocked" and scan.method == "scan"
    thetas = np.stack([R50_HOVER, R50_HOVER * 1.05] if options.get("g") == R50_G else [STABLE, TABLE2])
    y_scan, y_blocked = np.asarray(_run(scan, thetas)), np.asarray(_run(blocked, thetas))
    for i in range(2):
        np.testing.assert_allclose(y_blocked[i], y_scan[i], rtol=0, atol=1e-9 * np.max(np.abs(y_scan[i])))
    c_scan = paper_cost(y_scan, f.outputs)  # what simulator_cost computes for a scan simulator
    assert _rel(simulator_cost(blocked, thetas, f.outputs), c_scan) < 1e-6


def test_float32_cost_is_close_to_float64(segment=None, tolerance=2e-3):
    """float32 blocked costs within 2e-3 (absolute; costs run 0..16) of float64 on one 16 s open-loop run
    (1e-5 with 2 s segments; the open-loop float32 rounding depends on the CPU's vector code: 1.2e-3 on an
    AVX-512 host), and diverging in float32 exactly where the float32 scan does (unmeasured yaw
    states overflowing float32)."""
    f = _flight(1603, seed=2)
    options = dict(outputs=("p", "q", "phi", "theta"), segment=segment)
    sim, scan = make_simulator(f, **options), make_simulator(f, method="scan", **options)
    rng = np.random.default_rng(0)
    thetas = np.concatenate([
        TABLE2[None], TABLE2 * (1 + 0.2 * rng.uniform(-1, 1, size=(15, 40))), LOWER + (UPPER - LOWER) * rng.uniform(size=(16, 40))
    ])
    target = f.select(sim.outputs).outputs
    c64 = np.asarray(simulator_cost(sim, thetas, target))
    t32, m32 = jnp.asarray(thetas, jnp.float32), jnp.asarray(target, jnp.float32)
    c32 = np.asarray(simulator_cost(sim, t32, m32))
    s32 = np.asarray(simulator_cost(scan, t32, m32))
    assert c32.dtype == np.float32
    finite32 = c32 < 16.0
    assert finite32[:16].all() and np.array_equal(finite32, s32 < 16.0)
    np.testing.assert_allclose(c32[finite32], c64[finite32], rtol=0, atol=tolerance)


# a random draw inside the search box whose roll/pitch mode grows at 12 /s: it overflows float64 in 80 s
DIVERGING = np.array([
    -0.4586, -22.0024, 0.1111, 16.6986, -0.7545, 0.6101, 189.9583, 0.0, 0.0796, 0.0186,
    50.9831, 0.0, 0.0134, -0.85, 0.071, -0.8566, -0.8892, 11.3403, 5.519, -0.5964,
    1.467, 0.0042, 6.7101, 0.0, 4.8353, -33.289, 1.2134, -1.5315, 0.1712, 0.0,
    0.0, -0.0278, -0.1372, 0.5151, 0.0046, -2.3036, 58.9997, 2.1364, 0.7135, -0.784,
])


def test_diverging_candidates_get_the_worst_cost_never_nan():
    f = _flight(8001, seed=3)
    channels = ("p", "q", "phi", "theta")
    thetas = np.stack([TABLE2, DIVERGING, params_array({"tf": 1e-9}, base=TABLE2), np.full(40, np.nan)])
    for dtype in (jnp.float64, jnp.float32):
        cost = np.asarray(population_cost(jnp.asarray(thetas, dtype), f, outputs=channels))
        assert np.all(np.isfinite(cost)), cost
        assert cost[1] == 16.0 and cost[3] == 16.0  # 4 channels, each at the worst (1 - (-1))^2
        assert cost[0] < 16.0 and cost[2] <= 16.0
    scan = np.asarray(population_cost(thetas, f, outputs=channels, method="scan"))
    assert scan[1] == 16.0 and scan[3] == 16.0


def test_auto_picks_blocked_when_a_block_fits_the_segment():
    f = _flight(400)
    assert make_simulator(f).method == "blocked"
    assert make_simulator(f, segment=2.0).block == 20  # divisor of 200 nearest 16
    assert make_simulator(f, segment=0.37).method == "scan"  # 37 samples: prime, above the block range
    with pytest.raises(ValueError, match="blocked"):
        make_simulator(f, segment=0.37, method="blocked")
    with pytest.raises(ValueError, match="method"):
        make_simulator(f, method="fast")
    assert choose_block(0) == 16 and choose_block(50) == 10 and choose_block(7) == 7 and choose_block(101) is None


def test_population_cost_keeps_batch_shape_and_methods_agree():
    f = _flight(603, seed=4)
    rng = np.random.default_rng(1)
    thetas = (LOWER + (UPPER - LOWER) * rng.uniform(size=(2, 3, 40)))
    auto = np.asarray(population_cost(thetas, f, segment=1.0))
    scan = np.asarray(population_cost(thetas, f, segment=1.0, method="scan"))
    assert auto.shape == (2, 3)
    np.testing.assert_allclose(auto, scan, rtol=1e-6)


SHARDED = """
import os, sys
os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=2"
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np
from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, UPPER
from jaxheli.sim.population import simulator_cost
from jaxheli.sim.simulate import make_simulator
assert jax.local_device_count() == 2
rng = np.random.default_rng(0)
t = np.arange(1203) * 0.01
u = 0.05 * np.sin(2 * np.pi * np.array([0.3, 0.5, 0.7, 0.9]) * t[:, None])
f = FlightData(t, u, np.cumsum(rng.normal(size=(1203, 4)), axis=0), ("p", "q", "phi", "theta"))
sim = make_simulator(f, segment=1.0)
thetas = LOWER + (UPPER - LOWER) * rng.uniform(size=(131, 40))  # odd: padded to 132
one = np.asarray(simulator_cost(sim, thetas, f.outputs, shard=False))
two = np.asarray(simulator_cost(sim, thetas, f.outputs, shard=True))
auto = np.asarray(simulator_cost(sim, thetas, f.outputs))
np.testing.assert_allclose(two, one, rtol=1e-12)
np.testing.assert_array_equal(auto, two)
print("sharded ok", one.shape)
"""


def test_population_cost_sharded_over_two_host_devices_equals_one_device():
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", SHARDED], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "sharded ok (131,)" in out.stdout
