"""The segment restart's correction and its hand-written tangent against numpy references: the correction against
per-segment normal equations, the tangent against central finite differences of those same numpy equations."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.gap.segment_restart import restart_correction

N, K = 6, 3


def _numpy_correction(residual, F, H, P, noise_var, anchor, segment):
    """Each segment's restart moved by the least squares of its own readings, with ``P`` as the prior (the first
    segment's information plus ``diag(anchor)``): a loop."""
    out = np.zeros_like(residual)
    W = np.diag(1.0 / noise_var)
    for start in range(0, residual.shape[0], segment):
        r = residual[start:start + segment]
        phi = np.stack([H @ np.linalg.matrix_power(F, j) for j in range(1, len(r) + 1)])
        info = np.einsum("jka,kl,jlb->ab", phi, W, phi) + np.linalg.inv(P) + (np.diag(anchor) if start == 0 else 0)
        d = np.linalg.solve(info, np.einsum("jka,kl,jl->a", phi, W, r))
        out[start:start + segment] = phi @ d
    return out


def _problem(seed, m):
    rng = np.random.default_rng(seed)
    F = np.eye(N) * 1.01 + 0.05 * rng.standard_normal((N, N))  # slightly unstable, as the hover model is
    H = rng.standard_normal((K, N))
    A = rng.standard_normal((N, N))
    anchor = np.r_[np.zeros(N - 2), rng.uniform(1.0, 100.0, 2)]  # two states known at the start
    return (rng.standard_normal((m, K)), F, H, A @ A.T + 0.1 * np.eye(N), rng.uniform(0.5, 2.0, K), anchor)


@pytest.mark.parametrize("m, segment", [(30, 10), (29, 10), (7, 10), (31, 10)])
def test_correction_equals_per_segment_normal_equations(m, segment):
    args = _problem(m, m)
    got = np.asarray(restart_correction(*(jnp.asarray(a) for a in args), segment))
    np.testing.assert_allclose(got, _numpy_correction(*args, segment), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("m, segment", [(30, 10), (29, 10), (7, 10)])
def test_tangent_equals_finite_differences_in_every_argument(m, segment):
    args = _problem(100 + m, m)
    rng = np.random.default_rng(m)
    directions = [rng.standard_normal(a.shape) for a in args]
    directions[3] = directions[3] + directions[3].T  # a covariance moves symmetrically
    directions[5] = np.zeros_like(directions[5])  # the anchor is a constant of the predictor
    for which in range(len(args) - 1):  # one argument at a time, then all together
        tangent = [d if i == which else np.zeros_like(d) for i, d in enumerate(directions)]
        _check_tangent(args, tangent, segment)
    _check_tangent(args, directions, segment)


def _check_tangent(args, tangent, segment, h=1e-6):
    _, got = jax.jvp(lambda *a: restart_correction(*a, segment), tuple(jnp.asarray(a) for a in args),
                     tuple(jnp.asarray(t) for t in tangent))
    plus = _numpy_correction(*(a + h * t for a, t in zip(args, tangent)), segment)
    minus = _numpy_correction(*(a - h * t for a, t in zip(args, tangent)), segment)
    want = (plus - minus) / (2 * h)
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-6, atol=1e-7 * np.abs(want).max())


def test_jacobian_under_jit_and_vmap_equals_finite_differences():
    """The tangent batched over many directions (``jax.jacfwd``, as the Levenberg-Marquardt fit uses it)."""
    residual, F, H, P, var, anchor = (jnp.asarray(a) for a in _problem(7, 25))
    scale = jnp.asarray(np.random.default_rng(3).standard_normal((4, N, N)))

    def f(p):
        return restart_correction(residual * (1 + p[0]), F + jnp.einsum("i,iab->ab", p, scale), H, P, var, anchor,
                                  10)

    jac = np.asarray(jax.jit(jax.jacfwd(f))(jnp.zeros(4)))
    h = 1e-6
    want = np.stack([(np.asarray(f(h * e)) - np.asarray(f(-h * e))) / (2 * h) for e in np.eye(4)], axis=-1)
    np.testing.assert_allclose(jac, want, rtol=1e-6, atol=1e-7 * np.abs(want).max())
