"""The chunked forward-mode Jacobian (:mod:`jaxheli.optim.jacobian`) against ``jax.jacfwd`` and central differences,
and the least-squares solver's steps the same whether its Jacobian is pushed in chunks or at once."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.optim import jacobian
from jaxheli.optim.boxed_lm import boxed_least_squares, least_squares_solver


def _fn(x):
    t = jnp.linspace(0.0, 1.0, 50)
    return jnp.concatenate([jnp.sin(x[0] * t) * x[1:4].sum(), jnp.exp(-x[4] * t) * x[5] ** 2, x * x[6]])


def test_chunk_size_takes_every_direction_unless_the_tangents_exceed_the_budget(monkeypatch):
    assert jacobian.chunk_size(35, 34_000) == 35  # flight A's polish: all at once
    assert jacobian.chunk_size(35, 75_001 * 8) == 35  # 5 min at 250 Hz, 8 channels: all at once
    assert jacobian.chunk_size(35, 450_001 * 8) == 9  # 30 min: 9 directions at a time
    monkeypatch.setattr(jacobian, "TANGENT_BYTES", 1)
    assert jacobian.chunk_size(35, 100) == 1


@pytest.mark.parametrize("budget", [1 << 30, 3 * 107 * 8 * 8, 1])  # all at once; 3 (two chunks and one over); one
def test_chunked_jacobian_equals_jacfwd_and_differences(monkeypatch, budget):
    monkeypatch.setattr(jacobian, "TANGENT_BYTES", budget)
    x = jnp.array([1.3, 0.2, -0.5, 0.9, 0.7, -1.1, 0.4])
    r, J = jacobian.residuals_and_jacobian(_fn, x)  # traced anew for each budget
    assert J.shape == (107, 7)
    np.testing.assert_allclose(r, _fn(x), rtol=0, atol=0)
    np.testing.assert_allclose(J, jax.jacfwd(_fn)(x), rtol=1e-14, atol=1e-14)
    h = 1e-6
    central = np.stack([(_fn(x.at[i].add(h)) - _fn(x.at[i].add(-h))) / (2 * h) for i in range(7)], axis=1)
    np.testing.assert_allclose(J, central, atol=1e-7)


def test_solver_steps_are_the_same_with_the_jacobian_in_chunks(monkeypatch):
    """The box-constrained solver (:mod:`jaxheli.optim.boxed_lm`) takes the same steps with its Jacobian one
    direction at a time as with all at once."""
    target = _fn(jnp.array([1.1, 0.3, -0.2, 0.8, 0.5, -0.9, 0.6]))

    def fit(u, _):
        return _fn(2.0 * u - 1.0) - target

    def solve():
        return boxed_least_squares(fit, least_squares_solver("lm", 1e-10, 1e-10, 7), jnp.full(7, 0.55), None, 30)

    whole = solve()
    chunks = []
    size = jacobian.chunk_size
    monkeypatch.setattr(jacobian, "TANGENT_BYTES", 1)
    monkeypatch.setattr(jacobian, "chunk_size", lambda *a: chunks.append(size(*a)) or chunks[-1])
    chunked = solve()  # not jitted: traced again under the budget
    assert chunks and set(chunks) == {1}
    assert int(whole.num_steps) == int(chunked.num_steps) > 1
    np.testing.assert_allclose(chunked.value, whole.value, rtol=1e-12, atol=1e-12)
