"""Runs whose initial states are estimated: multiple shooting by variable projection.

An open-loop-unstable model simulated over a long record amplifies any error in its initial state; restarting from
the *measured* states instead (the simulator's ``x0="measured"`` restarts) injects the sensors' noise into every
run. Here every run (the whole record, or each ``segment`` of it) starts from the state that best explains that
run's measured outputs under ``theta``. The outputs are affine in a run's initial state,

    y_j[m] = f_j[m] + C Ad^m x_j,

with ``f_j`` the response to the sticks from rest, so each ``x_j`` is a small weighted linear least-squares fit
(weights: each measured channel's inverse variance over the record, the normalisation of PEM's residuals), solved
inside the simulation and differentiated through: Golub and Pereyra's variable projection. The initial states are
nuisance parameters eliminated exactly; what is left depends on ``theta`` alone, is the maximum-likelihood output
error for white measurement noise, and its Jacobian gives the parameters' Cramer-Rao bounds with the initial states
marginalised.

Layout (the simulator's restarts): run 0 covers samples ``0 .. L`` (``m = 0 .. L``), run ``j >= 1`` samples
``jL + 1 .. (j + 1) L`` (``m = 1 .. L``), the last one cut at the record's end; ``L`` is the segment length in
samples (the whole record for one run). Channels the simulator cannot restart from (unmeasured, or the authors'
stick-multiple flapping columns) get no weight.

Cost: about three simulations per ``theta``, every run advanced by one linear recursion over the ``L`` steps
(:mod:`jaxheli.sim.recursion`, whose tangent is cheap): the runs from rest, one backward (adjoint) pass that sums each
run's right-hand side ``sum_m (C Ad^m)' W e_j[m]``, and the free response from the fitted states, added to the runs
from rest. The Gram matrices ``sum_m (C Ad^m)' W C Ad^m`` (the same for all runs but the first and
the last) come from ``log2 L`` doublings of 13 x 13 matrices, never from the powers at every sample.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..model import build_ab, output_indices
from .discretize import Discrete, discretize
from .recursion import linear_recursion

Simulator = Any
"""A :class:`jaxheli.sim.simulate.Simulator` (which calls this module; not imported here, so no import cycle)."""

RIDGE = 1e-10
"""Tikhonov term of each run's normal equations, relative to their mean diagonal: a state the run's outputs cannot
see (e.g. the yaw-gyro state of a model without feedback) is set to zero instead of making the solve singular."""


def run_shape(n_samples: int, segment_samples: int) -> tuple[int, int]:
    """``(K, L)``: the number of runs of a record of ``n_samples`` restarted every ``segment_samples`` (0: one run
    over the record) and their length in steps (the last run may be shorter)."""
    L = max(segment_samples if segment_samples > 0 else n_samples - 1, 1)
    return max(1, -(-(n_samples - 1) // L)), L


def run_layout(n_samples: int, segment_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """``(sample, valid)``, each ``[K, L + 1]``: the sample index of step ``m`` of run ``j`` and whether it belongs
    to that run (see the module); ``segment_samples`` 0 means one run over the record."""
    K, L = run_shape(n_samples, segment_samples)
    j, m = np.meshgrid(np.arange(K), np.arange(L + 1), indexing="ij")
    sample = j * L + m
    valid = ((m >= 1) | (j == 0)) & (sample <= n_samples - 1)
    return np.where(valid, sample, n_samples), valid


def run_count(n_samples: int, segment_samples: int) -> int:
    """Runs of a record of ``n_samples`` restarted every ``segment_samples`` (0: one run)."""
    return run_shape(n_samples, segment_samples)[0]


def run_states(sim: Simulator, theta: Float[Array, "40"]) -> Float[Array, "K 13"]:
    """Each run's least-squares initial state under ``theta[40]`` (the states :func:`estimated_outputs` starts
    from), in :data:`jaxheli.model.STATE_NAMES` order."""
    return _project(sim, theta)[1]


def estimated_outputs(sim: Simulator, theta: Float[Array, "40"]) -> Float[Array, "N k"]:
    """``sim``'s outputs for one ``theta[40]``, every run started from its least-squares initial state."""
    d, x0, forced = _project(sim, theta)
    K, L = run_shape(sim.inputs.shape[0], sim.segment_samples)
    idx = tuple(int(i) for i in output_indices(sim.outputs))
    none = jnp.zeros((L, K, 0), d.Ad.dtype)
    free = linear_recursion(d.Ad.T, jnp.zeros((0, d.Ad.shape[0]), d.Ad.dtype), none, x0, False, idx)
    return _by_sample(forced + free, x0[0, np.array(idx)], sim.inputs.shape[0])


def _project(sim: Simulator, theta: Float[Array, "40"]) -> tuple[Discrete, Float[Array, "K 13"], Array]:
    """The discrete model, each run's least-squares initial state and the runs' outputs from rest (``[L, K, k]``,
    by step): the runs from rest, the right-hand sides by one backward (adjoint) pass over their weighted errors,
    the Gram matrices by :func:`_power_sums`."""
    idx = output_indices(sim.outputs)
    measured = sim.measured_states[:, idx]
    std = jnp.std(measured, axis=0)
    used = jnp.asarray(np.asarray(sim.measured_mask)[idx]) & (std > 0)
    weight = jnp.where(used, 1.0 / jnp.where(std > 0, std, 1.0) ** 2, 0.0)

    d = discretize(*build_ab(theta, sim.g), sim.dt, sim.hold)
    n, n_x = measured.shape[0], d.Ad.shape[0]
    K, L = run_shape(n, sim.segment_samples)
    u = jnp.pad(sim.inputs.astype(d.Ad.dtype), ((0, K * L + 1 - n), (0, 0)))
    sticks = jnp.concatenate([_by_step(u[:-1], K, L), _by_step(u[1:], K, L)], axis=-1)  # [L, K, 2m]
    rest = jnp.zeros((K, n_x), d.Ad.dtype)
    keep = tuple(int(i) for i in idx)
    forced = linear_recursion(d.Ad.T, jnp.concatenate([d.B0.T, d.B1.T]), sticks, rest, False, keep)  # [L, K, k]
    C = jnp.eye(n_x, dtype=d.Ad.dtype)[idx]  # [k, 13]
    seen = _by_step(jnp.ones((n - 1, 1), d.Ad.dtype), K, L)  # [L, K, 1]: 0 on the padding
    errors = (_by_step(measured[1:], K, L) - forced) * seen * weight[None, None]  # W e, [L, K, k]
    # lam_m = Ad' (lam_{m+1} + C' W e_m), backwards; lam_1 = sum_m (C Ad^m)' W e_m
    lam = linear_recursion(d.Ad, C @ d.Ad, errors, rest, True)[0]
    rhs = lam.at[0].add((measured[0] * weight) @ C)  # run 0 also holds step 0 (its run from rest is 0 there)
    Q = C.T @ (weight[:, None] * C)
    full, last = _power_sums(d.Ad, Q, (L, n - 1 - (K - 1) * L))
    gram = jnp.broadcast_to(d.Ad.T @ full @ d.Ad, (K, n_x, n_x)).at[-1].set(d.Ad.T @ last @ d.Ad).at[0].add(Q)
    eye = jnp.eye(n_x, dtype=gram.dtype)
    scale = RIDGE * jnp.trace(gram, axis1=-2, axis2=-1) / n_x + jnp.finfo(gram.dtype).tiny
    x0 = jnp.linalg.solve(gram + scale[:, None, None] * eye[None], rhs[..., None])[..., 0]
    return d, x0, forced


def _by_sample(y: Float[Array, "L K k"], first: Float[Array, " k"], n: int) -> Float[Array, "N k"]:
    """Outputs by step of each run (:func:`_by_step`'s layout) as the record's ``n`` samples, ``first`` at 0."""
    K, L = y.shape[1], y.shape[0]
    return jnp.concatenate([first[None], jnp.swapaxes(y, 0, 1).reshape(K * L, -1)[: n - 1]])


def _by_step(a: Float[Array, "M c"], K: int, L: int) -> Float[Array, "L K c"]:
    """Rows of a record, zero-padded, as the ``L`` scan steps of each of ``K`` runs: row ``i`` is step ``i % L`` of
    run ``i // L``."""
    return jnp.swapaxes(jnp.pad(a, ((0, K * L - a.shape[0]), (0, 0))).reshape(K, L, -1), 0, 1)


def _power_sums(
    Ad: Float[Array, "13 13"], Q: Float[Array, "13 13"], lengths: tuple[int, ...]
) -> Float[Array, "R 13 13"]:
    """``S(n) = sum_{m < n} (Ad^m)' Q Ad^m`` for each ``n`` of ``lengths`` (positive), by doubling
    (``S(2a) = S(a) + (Ad^a)' S(a) Ad^a``) and one scan over the binary digits of ``n``
    (``S(a + b) = S(a) + (Ad^a)' S(b) Ad^a``), lowest first; no power above ``Ad^n`` is formed."""
    bits = np.array([[(n >> i) & 1 for n in lengths] for i in range(max(lengths).bit_length())], bool)  # [B, R]
    first = jnp.asarray(bits[0])[:, None, None]
    acc = (jnp.where(first, Q[None], 0.0), jnp.where(first, Ad[None], jnp.eye(Ad.shape[0], dtype=Ad.dtype)[None]))  # S(a), Ad^a

    def digit(carry, bit):
        (S, P), (S_acc, P_acc) = carry
        S, P = S + P.T @ S @ P, P @ P  # S(2^i), Ad^(2^i)
        grown = (S_acc + jnp.swapaxes(P_acc, -1, -2) @ S[None] @ P_acc, P_acc @ P[None])
        acc = tuple(jnp.where(bit[:, None, None], new, old) for new, old in zip(grown, (S_acc, P_acc)))
        return ((S, P), acc), None

    (_, (sums, _)), _ = jax.lax.scan(digit, ((Q, Ad), acc), jnp.asarray(bits[1:]))
    return sums
