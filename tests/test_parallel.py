"""The parallel-in-time forms (jaxheli.sim.parallel) against the plain scan, and the choice between them.

Errors are measured against the scale of the trajectory so far: ``e_k = |x_par[k] - x_scan[k]|_inf / max_{i<=k}
|x_ref[i]|_inf``. Both forms sum the same terms in another order; a rounding error made at step ``i`` grows by
``Ad^(k-i)`` up to step ``k`` as the trajectory does, so (normwise, for a model whose eigenvectors are not too
ill-conditioned) ``e_k`` is about ``c u min(k, 1 / (1 - rho))`` for a stable ``Ad`` of spectral radius ``rho`` and
``c u k`` for an unstable one: linear in the steps, the growth ``rho^k`` itself divided out, so ``rho`` sets only
where float32 overflows (``rho^k |x| < 3.4e38``). ``u`` is the unit roundoff (2^-24 in float32, 2^-53 in float64).
Measured on Table 2 and Mettler's R-50 with their poles shifted by -1 .. +2 1/s (rho 0.990 .. 1.023 at 100 Hz,
eigenvector condition numbers 133 and 263), ``c`` was at most 0.75; the tests allow :data:`C_BOUND`. For the blocked
kernel ``k`` counts block starts (``N / L`` steps), the powers ``Ad^L`` being shared by both forms. In float64 that
is below 1e-12 for every ``N`` here, and the tests require the brief's 1e-10.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from jaxheli.benchmark.throughput import bench_flight
from jaxheli.model import G_SI, R50_G, R50_HOVER, TABLE2, build_ab, output_indices
from jaxheli.sim import forms
from jaxheli.sim.discretize import discretize
from jaxheli.sim.population import simulator_cost
from jaxheli.sim.recursion import linear_recursion
from jaxheli.sim.shooting import estimated_outputs
from jaxheli.sim.simulate import _run, make_simulator

U32, U64 = 2.0**-24, 2.0**-53
C_BOUND = 4.0
"""The constant the float32 tests allow in ``e_k <= C u min(k, 1/(1-rho))`` (measured: at most 0.75)."""

MODELS = [(TABLE2, G_SI, 0.0), (R50_HOVER, R50_G, 0.0), (TABLE2, G_SI, -1.0), (R50_HOVER, R50_G, 0.5)]
"""Unstable Table 2 and R-50 (rho 1.0005, 1.0031 per 0.01 s), a damped Table 2 (rho 0.990) and a more unstable
R-50 (all poles shifted by +0.5 1/s: rho 1.0081)."""

run = jax.jit(linear_recursion, static_argnames=("reverse", "keep", "form"))


def _discrete(theta, g, shift):
    """``(M, G) = (Ad', B0')`` of the hover model with every pole moved by ``shift`` 1/s, sampled at 0.01 s (scipy's
    zero-order hold)."""
    A, B = (np.asarray(m) for m in build_ab(jnp.asarray(theta), g))
    E = scipy.linalg.expm(np.block([[A + shift * np.eye(13), B], [np.zeros((4, 17))]]) * 0.01)
    return jnp.asarray(E[:13, :13].T), jnp.asarray(E[:13, 13:].T)


def _radius(M):
    """Spectral radius of ``M``."""
    return float(np.max(np.abs(np.linalg.eigvals(np.asarray(M)))))


def _errors(got, want, ref, time_axis=0):
    """``e_k`` of the module (the largest absolute value over every other axis)."""
    other = tuple(i for i in range(np.ndim(ref)) if i != time_axis)
    scale = np.maximum.accumulate(np.max(np.abs(ref), axis=other))
    return np.max(np.abs(np.asarray(got, float) - np.asarray(want, float)), axis=other) / np.maximum(scale, 1e-300)


def _sticks(n, batch=(), seed=0):
    return np.random.default_rng(seed).normal(size=(n,) + batch + (4,)) * 0.05


def test_choose_form_reads_the_table_and_the_overrides(monkeypatch, tmp_path):
    monkeypatch.delenv(forms.ENV, raising=False)
    monkeypatch.delenv(forms.TABLE_ENV, raising=False)
    assert forms.choose_form("population", 10**6) == "scan"  # this CPU: the table says scan
    assert forms.choose_form("recursion", 10**6, backend="cpu") == "scan"
    assert forms.choose_form("recursion", 10**4, backend="cuda") == "parallel"
    assert forms.choose_form("recursion", 8, backend="gpu") == "scan"  # below the threshold
    assert forms.choose_form("population", 10**4, backend="gpu", elements=forms.MAX_PARALLEL_ELEMENTS + 1) == "scan"
    assert forms.choose_form("population", 10, "parallel") == "parallel"
    monkeypatch.setenv(forms.ENV, "parallel")
    assert forms.choose_form("recursion", 10) == "parallel"
    assert forms.choose_form("recursion", 10, "scan") == "scan"  # an explicit form wins over the variable
    monkeypatch.setenv(forms.ENV, "sideways")
    with pytest.raises(ValueError, match=forms.ENV):
        forms.choose_form("recursion", 10)
    monkeypatch.delenv(forms.ENV)
    bench = tmp_path / "bench.json"
    bench.write_text('{"time_forms": {"selection": {"cpu": {"population": 100, "recursion": null}}}}')
    monkeypatch.setenv(forms.TABLE_ENV, str(bench))
    assert forms.choose_form("population", 99) == "scan" and forms.choose_form("population", 100) == "parallel"
    assert forms.choose_form("recursion", 10**6) == "scan"


@pytest.mark.parametrize("reverse", [False, True])
def test_recursion_equals_the_scan_in_float64(reverse):
    """Forward and adjoint recursions of stable and unstable hover models, two runs side by side, cut every 400
    steps (restarts), 1,600 steps: within 1e-10 of the scan."""
    n = 1600
    carry = jnp.asarray(np.arange(n) % 400 != 0, float)
    v = jnp.asarray(_sticks(n, (2,)))
    x0 = jnp.asarray(np.random.default_rng(1).normal(size=(2, 13)))
    for theta, g, shift in MODELS:
        M, G = _discrete(theta, g, shift)
        scan = run(M, G, v, x0, reverse, None, carry, form="scan")
        parallel = run(M, G, v, x0, reverse, None, carry, form="parallel")
        assert np.max(_errors(parallel, scan, scan)) < 1e-10


def test_recursion_gradient_equals_the_scans():
    """Reverse-mode gradients (the tangent rule transposed) with respect to parameters of the matrices, the sticks and
    the start, through the recursion (kept columns, restarts), equal the scan's to 1e-10 of their largest entry;
    forward mode: the next test."""
    n = 600
    carry = jnp.asarray(np.arange(n) % 150 != 0, float)
    M0, G0 = _discrete(R50_HOVER, R50_G, 0.0)
    v = jnp.asarray(_sticks(n))
    x0 = jnp.asarray(np.linspace(-1, 1, 13))

    @jax.jit
    def gradients(p):
        def loss(p, form):
            M = M0 * jnp.cos(p[0]) + p[1] * jnp.eye(13)
            out = linear_recursion(M, G0 * p[2], v * p[3], x0 * p[4], False, (2, 3, 4, 5), carry, form)
            return jnp.sum(out**2)

        return jax.grad(loss)(p, "scan"), jax.grad(loss)(p, "parallel")

    scan, parallel = map(np.asarray, gradients(jnp.array([0.01, 0.002, 1.1, 0.9, 0.5])))
    np.testing.assert_allclose(parallel, scan, rtol=0, atol=1e-10 * np.max(np.abs(scan)))


@eqx.filter_jit
def _estimated_and_jacobian(sim, theta):
    """``(outputs, d outputs / d theta)``, one forward-mode pass."""
    jacobian, outputs = jax.jacfwd(lambda t: (estimated_outputs(sim, t),) * 2, has_aux=True)(theta)
    return outputs, jacobian


def test_estimated_runs_and_their_jacobian_equal_the_scans():
    """The output-error polish's simulation (initial states by variable projection, 1-s runs: forward and adjoint
    recursions) and its Jacobian over the 40 parameters, parallel against scan, on an unstable model."""
    flight = bench_flight(601)
    (y_scan, j_scan), (y_par, j_par) = (
        map(np.asarray, _estimated_and_jacobian(make_simulator(flight, x0="estimated", segment=1.0, time_form=form),
                                                jnp.asarray(TABLE2)))
        for form in ("scan", "parallel"))
    np.testing.assert_allclose(y_par, y_scan, rtol=0, atol=1e-10 * np.max(np.abs(y_scan)))
    column = np.max(np.abs(j_scan), axis=(0, 1))  # each parameter's largest sensitivity
    assert np.all(np.abs(j_par - j_scan) <= 1e-10 * column + 1e-300)


@pytest.mark.parametrize("shift", [-1.0, 0.0, 1.0])
def test_float32_error_grows_as_stated(shift):
    """float32, 4,000 steps, Table 2 with its poles shifted (rho 0.990, 1.0005, 1.0105): every ``e_k`` within
    ``C u min(k, 1/(1 - rho))`` (the module), and both forms as close to the float64 scan as to each other."""
    n = 4000
    M, G = _discrete(TABLE2, G_SI, shift)
    rho = _radius(M)
    v = _sticks(n)
    ref = np.asarray(run(M, G, jnp.asarray(v), jnp.zeros(13), form="scan"))
    M32, G32, v32 = (jnp.asarray(a, jnp.float32) for a in (M, G, v))
    scan, parallel = (np.asarray(run(M32, G32, v32, jnp.zeros(13, jnp.float32), form=form))
                      for form in ("scan", "parallel"))
    k = np.arange(1, n + 1)
    steps = np.minimum(k, 1.0 / (1.0 - rho)) if rho < 1 else k
    assert np.all(_errors(parallel, scan, ref) <= C_BOUND * U32 * steps)
    assert np.all(_errors(parallel, ref, ref) <= C_BOUND * U32 * steps)
    assert np.all(_errors(scan, ref, ref) <= C_BOUND * U32 * steps)


@eqx.filter_jit
def _outputs_and_cost(sim, thetas, target):
    return sim(thetas), simulator_cost(sim, thetas, target)


def _numpy_rollout(theta, g, flight, hold, segment=None, x0="zero", reset="carry"):
    """The simulator's outputs by a Python loop over the samples (scipy's exact discretisation; restarts every
    ``segment`` s from the measured states, the unmeasured ones carried), what ``method="scan"`` computes on a flight
    whose channels are all measured states."""
    A, B = (np.asarray(m) for m in build_ab(jnp.asarray(theta), g))
    dt, n, m = flight.dt, flight.n_samples, 4
    if hold == "foh":
        E = scipy.linalg.expm(np.block([[A, B, np.zeros((13, m))], [np.zeros((m, 13 + m)), np.eye(m) / dt],
                                        [np.zeros((m, 13 + 2 * m))]]) * dt)
        Ad, B1 = E[:13, :13], E[:13, 13 + m:]
        B0 = E[:13, 13:13 + m] - B1
    else:
        E = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, 13 + m))]]) * dt)
        Ad, B0, B1 = E[:13, :13], E[:13, 13:], np.zeros((13, m))
    idx, u = output_indices(flight.output_names), flight.inputs
    measured = np.zeros((n, 13))
    measured[:, idx] = flight.outputs
    mask = np.isin(np.arange(13), idx)
    x = measured[0] if isinstance(x0, str) and x0 == "measured" else (np.zeros(13) if isinstance(x0, str) else x0)
    out = [x[idx]]
    every = 0 if segment is None else int(round(segment / dt))
    for k in range(1, n):
        x = Ad @ x + B0 @ u[k - 1] + B1 @ u[k]
        out.append(x[idx])
        if every and k % every == 0:
            x = np.where(mask, measured[k], x)
    return np.array(out)


def _pair(flight, **options):
    """The blocked kernel with scanned and with parallel block starts."""
    scan, parallel = (make_simulator(flight, method="blocked", time_form=form, **options)
                      for form in ("scan", "parallel"))
    assert parallel.plan(2).parallel and not scan.plan(2).parallel
    return scan, parallel


def _candidates(theta, seed=0):
    return np.stack([theta, theta * (1 + 0.03 * np.random.default_rng(seed).uniform(-1, 1, 40))])


def test_blocked_kernel_with_restarts_equals_the_scan():
    """First-order hold, restarts every 0.4 s from the measured states carrying the others (``reset="zero"``
    multiplies them by 0 instead of 1), unstable Table 2: outputs of the parallel block starts within 1e-10 of the
    trajectory so far of the per-sample loop, the paper's cost within 1e-10 relative of the scanned block starts';
    in float32 within the stated bound over the ``N / L`` block starts of the scanned block starts' float32."""
    flight, options = bench_flight(801), dict(hold="foh", segment=0.4, reset="carry", x0="measured")
    scan, parallel = _pair(flight, **options)
    thetas = _candidates(TABLE2)
    ref = np.stack([_numpy_rollout(t, G_SI, flight, **options) for t in thetas])
    (_, c_scan), (y_par, c_par) = (_outputs_and_cost(s, thetas, flight.outputs) for s in (scan, parallel))
    assert np.max(_errors(y_par, ref, ref, time_axis=1)) < 1e-10
    np.testing.assert_allclose(np.asarray(c_par), np.asarray(c_scan), rtol=1e-10)
    t32 = jnp.asarray(thetas, jnp.float32)
    y_scan32, y_par32 = (np.asarray(_run(s, t32)) for s in (scan, parallel))
    steps = np.maximum(np.arange(flight.n_samples) // scan.block, 1)  # block starts before each sample
    assert np.all(_errors(y_par32, y_scan32, ref, time_axis=1) <= C_BOUND * U32 * steps)


def test_blocked_kernel_over_one_long_run_equals_the_scan():
    """Zero-order hold, one run of 12 s from a given state (the paper's simulation), Mettler's unstable R-50:
    within 1e-10 of the trajectory so far of the per-sample loop."""
    flight, options = bench_flight(1203), dict(hold="zoh", x0=np.linspace(-0.5, 0.5, 13))
    _, parallel = _pair(flight, g=R50_G, **options)
    thetas = _candidates(R50_HOVER)
    ref = np.stack([_numpy_rollout(t, R50_G, flight, **options) for t in thetas])
    assert np.max(_errors(_run(parallel, thetas), ref, ref, time_axis=1)) < 1e-10
