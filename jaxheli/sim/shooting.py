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

Cost: about three simulations per ``theta``, each one linear recursion over the whole record whose carry is cut where
a run starts afresh (:mod:`jaxheli.sim.recursion`, whose tangent is cheap; in the simulator's
:attr:`~jaxheli.sim.simulate.Simulator.time_form`): the runs from rest, one backward (adjoint)
pass that sums each run's right-hand side ``sum_m (C Ad^m)' W e_j[m]``, and the free response from the fitted states,
added to the runs from rest. The Gram matrices ``sum_m (C Ad^m)' W C Ad^m`` (the same for all runs but the first and
the last) come from ``log2 L`` doublings of 13 x 13 matrices, never from the powers at every sample. ``L`` is a
run-time value (:attr:`~jaxheli.sim.simulate.Simulator.run_samples`), the number of runs bounded by
:func:`run_bound`: a fit compiles one program for runs of every length (advancing the runs side by side as
``[K, L]`` would compile one per run length).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float, Int
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


SHORTEST_RUN_S = 1.0
"""Runs at least this long (s) share one compiled simulation on a record: the number of runs is bounded by that of
runs this long (:func:`run_bound`), the run length itself a run-time value."""


def run_bound(n_samples: int, segment_samples: int, dt: float) -> int:
    """The compiled bound on the number of runs: those of ``segment_samples`` or of :data:`SHORTEST_RUN_S`, the
    more."""
    return max(run_count(n_samples, segment_samples), run_count(n_samples, max(1, int(round(SHORTEST_RUN_S / dt)))))


def run_states(sim: Simulator, theta: Float[Array, "40"]) -> Float[Array, "K 13"]:
    """Each run's least-squares initial state under ``theta[40]`` (the states :func:`estimated_outputs` starts
    from), in :data:`jaxheli.model.STATE_NAMES` order (``sim`` concrete: its runs are counted on the host)."""
    return _project(sim, theta)[1][: run_count(sim.inputs.shape[0], sim.restart_samples)]


def estimated_outputs(sim: Simulator, theta: Float[Array, "40"]) -> Float[Array, "N k"]:
    """``sim``'s outputs for one ``theta[40]``, every run started from its least-squares initial state."""
    d, x0, forced = _project(sim, theta)
    L, carry = _steps(sim)
    idx = tuple(int(i) for i in output_indices(sim.outputs))
    n = sim.inputs.shape[0]
    starting = (1.0 - carry)[:, None] * x0[jnp.minimum(jnp.arange(n - 1) // L, x0.shape[0] - 1)]  # [N - 1, 13]
    free = linear_recursion(d.Ad.T, d.Ad.T, starting, x0[0], False, idx, carry, sim.time_form)
    return jnp.concatenate([x0[0, np.array(idx)][None], forced + free])


def _steps(sim: Simulator) -> tuple[Int[Array, ""], Float[Array, " N-1"]]:
    """The run length ``L`` in steps (a run-time value) and each step's carry: 0 where the step leaves a run's first
    sample ``jL``, ``j >= 1`` (the run starts afresh there), else 1."""
    n = sim.inputs.shape[0]
    L = jnp.where(sim.run_samples > 0, jnp.minimum(sim.run_samples, n - 1), n - 1)
    step = jnp.arange(n - 1)
    return L, ((step == 0) | (step % L != 0)).astype(sim.measured_states.dtype)


def _project(sim: Simulator, theta: Float[Array, "40"]) -> tuple[Discrete, Float[Array, "R 13"], Array]:
    """The discrete model, each run's least-squares initial state (``R`` = ``sim.max_runs`` rows, those past the
    record's runs zero) and the outputs from rest of every run, one recursion over the record (``[N - 1, k]``, samples
    1 on): the right-hand sides by one backward (adjoint) pass over the weighted errors, the Gram matrices by
    :func:`_power_sums`."""
    idx = output_indices(sim.outputs)
    measured = sim.measured_states[:, idx]
    std = jnp.std(measured, axis=0)
    used = jnp.asarray(np.asarray(sim.measured_mask)[idx]) & (std > 0)
    weight = jnp.where(used, 1.0 / jnp.where(std > 0, std, 1.0) ** 2, 0.0)

    d = discretize(*build_ab(theta, sim.g), sim.dt, sim.hold)
    n, n_x = measured.shape[0], d.Ad.shape[0]
    L, carry = _steps(sim)
    K = (n - 2) // L + 1
    u = sim.inputs.astype(d.Ad.dtype)
    rest = jnp.zeros((n_x,), d.Ad.dtype)
    keep = tuple(int(i) for i in idx)
    forced = linear_recursion(d.Ad.T, jnp.concatenate([d.B0.T, d.B1.T]), jnp.concatenate([u[:-1], u[1:]], -1), rest,
                              False, keep, carry, sim.time_form)  # [N - 1, k]
    C = jnp.eye(n_x, dtype=d.Ad.dtype)[idx]  # [k, 13]
    errors = (measured[1:] - forced) * weight[None]  # W e, samples 1 on
    # mu_s = (c mu_{s+1} + e_{s+1} W C) Ad backwards, cut after each run's last sample: run j's sum is mu_{jL}
    ends = ((jnp.arange(n - 1) + 1) % L != 0).astype(d.Ad.dtype)
    mu = linear_recursion(d.Ad, C @ d.Ad, errors, rest, True, None, ends, sim.time_form)
    run = jnp.arange(sim.max_runs)
    rhs = mu[jnp.minimum(run * L, n - 2)] * (run < K)[:, None]
    rhs = rhs.at[0].add((measured[0] * weight) @ C)  # run 0 also holds step 0 (its run from rest is 0 there)
    Q = C.T @ (weight[:, None] * C)
    full, last = _power_sums(d.Ad, Q, jnp.stack([L, n - 1 - (K - 1) * L]), (n - 1).bit_length())
    eye = jnp.eye(n_x, dtype=d.Ad.dtype)
    gram = jnp.where((run == K - 1)[:, None, None], d.Ad.T @ last @ d.Ad, d.Ad.T @ full @ d.Ad)
    gram = jnp.where((run < K)[:, None, None], gram + jnp.where((run == 0)[:, None, None], Q, 0.0), eye)
    scale = RIDGE * jnp.trace(gram, axis1=-2, axis2=-1) / n_x + jnp.finfo(gram.dtype).tiny
    x0 = jnp.linalg.solve(gram + scale[:, None, None] * eye[None], rhs[..., None])[..., 0]
    return d, x0, forced


def _power_sums(
    Ad: Float[Array, "13 13"], Q: Float[Array, "13 13"], lengths: Int[Array, " R"], digits: int
) -> Float[Array, "R 13 13"]:
    """``S(n) = sum_{m < n} (Ad^m)' Q Ad^m`` for each ``n`` of ``lengths`` (positive run-time values below
    ``2^digits``), by doubling (``S(2a) = S(a) + (Ad^a)' S(a) Ad^a``) and one scan over the binary digits of ``n``
    (``S(a + b) = S(a) + (Ad^a)' S(b) Ad^a``), lowest first."""
    bits = (lengths[None, :] >> jnp.arange(max(digits, 1))[:, None]) & 1 == 1  # [B, R]
    first = bits[0][:, None, None]
    eye = jnp.eye(Ad.shape[0], dtype=Ad.dtype)
    acc = (jnp.where(first, Q[None], 0.0), jnp.where(first, Ad[None], eye[None]))  # S(a), Ad^a

    def digit(carry, bit):
        (S, P), (S_acc, P_acc) = carry
        S, P = S + P.T @ S @ P, P @ P  # S(2^i), Ad^(2^i)
        grown = (S_acc + jnp.swapaxes(P_acc, -1, -2) @ S[None] @ P_acc, P_acc @ P[None])
        acc = tuple(jnp.where(bit[:, None, None], new, old) for new, old in zip(grown, (S_acc, P_acc)))
        return ((S, P), acc), None

    (_, (sums, _)), _ = jax.lax.scan(digit, ((Q, Ad), acc), bits[1:])
    return sums
