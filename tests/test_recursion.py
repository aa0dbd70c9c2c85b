"""The linear recursion's values and hand-written tangent against a numpy loop and JAX's own tangent of a plain scan."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.sim.recursion import linear_recursion

L, K, N, C = 23, 3, 5, 2


CUT = np.ones(L)
CUT[[4, 11, 12]] = 0.0  # steps that start afresh (runs of one recursion)


def _numpy(M, G, v, x0, reverse, keep, carry=None):
    """The recursion by a Python loop over the steps."""
    out, x = np.zeros(v.shape[:-1] + (M.shape[0],)), np.array(x0)
    carry = np.ones(L) if carry is None else carry
    for m in (range(L - 1, -1, -1) if reverse else range(L)):
        x = carry[m] * (x @ M) + v[m] @ G
        out[m] = x
    return out if keep is None else out[..., list(keep)]


def _plain(M, G, v, x0, reverse, keep, carry=None):
    """The same recursion as one ``lax.scan`` that JAX differentiates itself."""

    def step(x, inputs):
        vm, c = inputs
        x = c * (x @ M) + vm @ G
        return x, x

    out = jax.lax.scan(step, x0, (v, jnp.ones(L) if carry is None else carry), reverse=reverse)[1]
    return out if keep is None else out[..., np.array(keep)]


def _args(seed: int):
    rng = np.random.default_rng(seed)
    M = 0.9 * np.linalg.qr(rng.normal(size=(N, N)))[0]
    return (M, rng.normal(size=(C, N)), rng.normal(size=(L, K, C)), rng.normal(size=(K, N)))


@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("keep", [None, (4, 0, 2)])
@pytest.mark.parametrize("carry", [None, CUT])
def test_values_equal_a_numpy_loop(reverse, keep, carry):
    args = _args(0)
    got = linear_recursion(*map(jnp.asarray, args), reverse, keep, None if carry is None else jnp.asarray(carry))
    np.testing.assert_allclose(np.asarray(got), _numpy(*args, reverse, keep, carry), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("keep", [None, (1, 3)])
@pytest.mark.parametrize("which", [0, 1, 2, 3, None])
@pytest.mark.parametrize("carry", [None, CUT])
def test_tangent_equals_jaxs_own_and_finite_differences(reverse, keep, which, carry):
    """Each argument's tangent alone, and all together, against JAX's tangent of the plain scan and against
    central differences of the numpy loop; with the recursion cut at some steps too."""
    primals = tuple(map(jnp.asarray, _args(1)))
    rng = np.random.default_rng(2)
    tangents = tuple(jnp.asarray(rng.normal(size=p.shape)) if which in (None, i) else jnp.zeros_like(p)
                     for i, p in enumerate(primals))
    cut = None if carry is None else jnp.asarray(carry)
    out, dout = jax.jvp(lambda *a: linear_recursion(*a, reverse, keep, cut), primals, tangents)
    ref_out, ref_dout = jax.jvp(lambda *a: _plain(*a, reverse, keep, cut), primals, tangents)
    np.testing.assert_allclose(np.asarray(out), np.asarray(ref_out), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.asarray(dout), np.asarray(ref_dout), rtol=1e-10, atol=1e-10)
    h = 1e-6
    ahead = _numpy(*(np.asarray(p) + h * np.asarray(t) for p, t in zip(primals, tangents)), reverse, keep, carry)
    behind = _numpy(*(np.asarray(p) - h * np.asarray(t) for p, t in zip(primals, tangents)), reverse, keep, carry)
    np.testing.assert_allclose(np.asarray(dout), (ahead - behind) / (2 * h), rtol=1e-6, atol=1e-6)


def test_jacobians_forward_and_reverse_through_a_parameterised_matrix():
    """``jit(jacfwd)`` and ``jacrev`` (the tangent transposed) of a recursion whose matrices depend on parameters
    equal JAX's own of the plain scan."""
    M0, G0, v, x0 = map(jnp.asarray, _args(3))

    def model(fn, p):
        M = M0 * jnp.cos(p[0]) + p[1] * jnp.eye(N)
        return fn(M, G0 * p[2], v, x0 * p[3], True, (0, 4)).sum(axis=1)

    p = jnp.array([0.1, 0.05, 1.3, -0.7])
    ref = jax.jacfwd(lambda q: model(_plain, q))(p)
    np.testing.assert_allclose(np.asarray(jax.jit(jax.jacfwd(lambda q: model(linear_recursion, q)))(p)),
                               np.asarray(ref), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(np.asarray(jax.jacrev(lambda q: model(linear_recursion, q))(p)),
                               np.asarray(ref), rtol=1e-10, atol=1e-10)
