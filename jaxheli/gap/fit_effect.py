"""Fit candidate effects: one compiled Levenberg-Marquardt solve (the engines' driver,
:func:`jaxheli.optim.boxed_lm.boxed_least_squares`) run for each candidate row in turn. Not ``vmap``: vmapped, the
solves, each a loop over forward-mode scans, can deadlock XLA CPU's runtime with every thread waiting. Not
``lax.map`` either: a step inside the map's loop is slower than run alone, and the mapped program compiles anew for
every row count. The row fits of a joint re-identification compile with :data:`jaxheli._xla.SOLVE_OFTEN`: a diagnosis
runs that program 40 to 50 times, each step a Jacobian over the 40 base parameters too, so it keeps LLVM's
optimisations. A program run once or a few times (the base frozen: a handful of unknowns; a row that walks the output
biases, whose filter is larger; a fit on both flights) compiles quick (:data:`jaxheli._xla.QUICK_COMPILE`).

Every candidate frees ``K`` entries of ``eta`` (``index[C, K]``, padded with a dummy slot), each in its
physical box (:func:`jaxheli.effects.registry.box`), started at the effect's start values. With the base
model frozen, the base ``theta`` stays as given; re-identified jointly (``theta_box`` given), the 40 base
parameters are freed too, in their box, so an effect is fitted *with* the base model the user would
re-identify, not on top of a base that already absorbed part of it. Both boxes go through the engines'
transform (:class:`jaxheli.bounds.Bounds`: unit coordinates, the clipped point simulated, a penalty outside,
iterates within the solver's margin of the box).

The residuals are the predictor's normalised output errors on the training flight (their sum of squares
is ``N`` times the summed per-channel gap), so the fit minimises the training gap directly. Standard
errors are Cramer-Rao style, ``s^2 (J^T J)^+`` with ``J`` the Jacobian (over every free parameter, base
ones included) at the optimum and ``s^2 = RSS / (N_res - K)``, inflated for coloured residuals by the
AR(1) factor ``(1 + r1) / (1 - r1)`` (``r1``: the residuals' lag-1 autocorrelation, averaged over
channels), i.e. counting effective samples ``n_eff = N_res (1 - r1) / (1 + r1)``.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float, Int
from .._xla import SOLVE_OFTEN, quick_jit, warn_if_unconfigured
from ..bounds import Bounds
from ..cost import nmse
from ..effects import registry as fx
from ..effects.plant import layout, no_effect, size
from ..model import N_PARAMS
from ..optim.boxed_lm import boxed_least_squares, least_squares_solver, step_bound
from .predictor import Predictor


def embed(base: Float[Array, "E"], index: Int[Array, "K"], z: Float[Array, "K"]) -> Float[Array, "E"]:
    """``eta``: ``base`` with the slots ``index`` set to ``z`` (slot ``E`` is a dummy that is dropped)."""
    return jnp.concatenate([base, jnp.zeros(1, base.dtype)]).at[index].set(z)[:-1]


def effect_eta(
    effect: str, params: Mapping[str, fx.Estimate], outputs: tuple[str, ...],
    nuisance: Mapping[str, float] | None = None,
) -> Float[np.ndarray, "E"]:
    """``eta`` of a fitted effect (a ranking entry's or the final fit's): its fitted ``params`` (as
    :func:`~jaxheli.effects.registry.describe` names them) and ``nuisance`` values (by name,
    :func:`~jaxheli.effects.registry.nuisance`) on the no-effect vector; ``effect`` may be a combination ``"a+b"``."""
    eta = no_effect(outputs)
    for p in fx.nuisance(outputs):
        eta[p.slot] = (nuisance or {}).get(p.name, eta[p.slot])
    for part in effect.split("+"):
        for p in fx.params(part, outputs):
            if p.name not in params:
                raise ValueError(f"effect {effect!r}: fitted parameter {p.name!r} missing from its entry")
            eta[p.slot] = params[p.name].value
    return eta


def fitted_nuisance(value: np.ndarray, outputs: tuple[str, ...], exclude: Collection[str] = ()) -> dict[str, float]:
    """The nuisance parameters a row fitted in its trailing columns (:func:`with_reference`),
    by name, but those in ``exclude`` (the effect's own parameters)."""
    ps = fx.nuisance(outputs)
    tail = np.asarray(value, np.float64)[len(value) - len(ps):]
    return {p.name: float(v) for p, v in zip(ps, tail) if p.name not in exclude}


class EffectRows(eqx.Module):
    """The candidates of one batched fit: ``eta`` slots ``index[C, K]``, start values and box (padding: the
    dummy slot, pinned at 0). Row 0 is the reference when built by :func:`with_reference`."""

    index: Int[Array, "C K"]
    start: Float[Array, "C K"]
    lower: Float[Array, "C K"]
    upper: Float[Array, "C K"]


def with_reference(index, start, lower, upper, pad: int, shared=None) -> EffectRows:
    """:class:`EffectRows` from :func:`~jaxheli.effects.registry.candidate_arrays`' arrays, with a first row
    that frees no effect (every slot the dummy ``pad``): the base model fitted alone, the yardstick every
    candidate is credited against. ``shared`` (``(slot[S], start[S], lower[S], upper[S])``,
    :func:`~jaxheli.effects.registry.nuisance_arrays`) adds slots every row frees, the reference's included,
    as trailing columns (the dummy in a row that frees the slot already)."""
    rows = [np.asarray(index), np.asarray(start), np.asarray(lower), np.asarray(upper)]
    first = [np.full_like(rows[0][:1], pad)] + [np.zeros_like(a[:1]) for a in rows[1:]]
    rows = [np.concatenate([f, a], axis=0) for f, a in zip(first, rows)]
    if shared is not None:
        slot = np.asarray(shared[0])
        held = np.any(rows[0][:, :, None] == slot[None, None, :], axis=1)
        extra = [np.where(held, fill, np.broadcast_to(np.asarray(a), held.shape))
                 for a, fill in zip(shared, (pad, 0.0, 0.0, 0.0))]
        rows = [np.concatenate([a, e.astype(a.dtype)], axis=1) for a, e in zip(rows, extra)]
    return EffectRows(*(jnp.asarray(a) for a in rows))


class EffectFit(eqx.Module):
    """Fitted candidates: effect values ``z[C, K]`` and standard errors, base parameters ``theta[C, 40]``
    (the given ones when frozen), training RSS, effective residual count, number of effect parameters the
    fit resolved, solver steps, converged flags."""

    z: Float[Array, "C K"]
    stderr: Float[Array, "C K"]
    theta: Float[Array, "C 40"]
    rss: Float[Array, "C"]
    n_eff: Float[Array, "C"]
    k_active: Int[Array, "C"]
    steps: Int[Array, "C"]
    converged: Array


MAX_STEPS = 15
"""Levenberg-Marquardt steps per candidate fit by default: the blind check's, on whose calibration seeds the
diagnosis's thresholds were set (``jaxheli/gap/thresholds.json``)."""


def fit_candidates(
    pred: Predictor,
    theta: Float[Array, "40"],
    base: Float[Array, "E"],
    cand: EffectRows,
    max_steps: int = MAX_STEPS,
    theta_box: Bounds | None = None,
    once: bool = False,
) -> EffectFit:
    """Fit every candidate on ``pred``'s flight (one compiled LM solve, :func:`_fit_row`, run for each row in turn;
    ``max_steps`` is static); with ``theta_box`` the base parameters are re-identified jointly in that box (it must
    contain ``theta``), else held at ``theta``. ``once``: this program runs once in the process (compiled quick, see
    the module)."""
    warn_if_unconfigured()
    rows = (cand.index, cand.start, cand.lower, cand.upper)
    walk = _walk_slots(pred.outputs)
    base_walks = bool(np.any(np.asarray(base)[walk]))
    limit, bound = jnp.asarray(max_steps), step_bound(max_steps)
    walks = [base_walks or bool(np.isin(np.asarray(cand.index[i]), walk).any()) for i in range(rows[0].shape[0])]
    often = theta_box is not None and not once
    programs = [_optimised_row if often and not w else _quick_row for w in walks]
    fits = [fit(pred.for_walks(w), theta, base, *(r[i] for r in rows), limit, bound, theta_box)
            for i, (fit, w) in enumerate(zip(programs, walks))]
    return EffectFit(*(jnp.stack(parts) for parts in zip(*fits)))


def _walk_slots(outputs: tuple[str, ...]) -> Int[np.ndarray, "W"]:
    """The slots of ``eta`` of the output biases' walks (:func:`~jaxheli.gap.kalman.gust_filter`): a fit or score
    whose ``eta`` leaves them all zero runs the predictor without the bias states (:meth:`Predictor.for_walks`)."""
    return np.arange(*layout(outputs)["walk"].indices(size(outputs)))


def _fit_row(
    pred: Predictor,
    theta: Float[Array, "40"],
    base: Float[Array, "E"],
    idx: Int[Array, "K"],
    z0: Float[Array, "K"],
    lo: Float[Array, "K"],
    hi: Float[Array, "K"],
    limit: Int[Array, ""],
    bound: int,
    theta_box: Bounds | None,
) -> tuple[Array, ...]:
    """One candidate row's fit of at most ``limit`` steps (``bound`` the compiled limit,
    :func:`~jaxheli.optim.boxed_lm.step_bound`): :class:`EffectFit`'s fields without the leading axis."""
    joint = theta_box is not None
    box = Bounds(jnp.concatenate([theta_box.lower, lo]), jnp.concatenate([theta_box.upper, hi])) if joint \
        else Bounds(lo, hi)
    p0 = jnp.concatenate([theta, z0]) if joint else z0

    def split(u):
        p = box.from_unit(Bounds.clip_unit(u))
        return (p[:N_PARAMS], p[N_PARAMS:]) if joint else (theta, p)

    def fit_res(u):
        th, z = split(u)
        return pred.residuals(th, embed(base, idx, z))

    u0 = box.to_unit(p0)
    sol = boxed_least_squares(lambda u, _: fit_res(u), least_squares_solver("lm", 1e-6, 1e-8, u0.shape[0]), u0,
                              None, bound, limit=limit, settle=0)  # fit_res is of the clipped point already
    u = sol.value
    J, res = jax.jacfwd(lambda v: (fit_res(v),) * 2, has_aux=True)(u)  # one copy of the predictor for both
    rss = jnp.sum(res**2)
    active = jnp.any(J != 0, axis=0) & (box.width > 0)
    colour = _colour_factor(res.reshape(pred.measured.shape))
    cov = rss / (res.shape[0] - jnp.sum(active)) * colour * jnp.linalg.pinv(J.T @ J)
    stderr = jnp.where(active, box.width * jnp.sqrt(jnp.abs(jnp.diag(cov))), 0.0)
    th, z = split(u)
    k = z0.shape[0]
    return z, stderr[-k:], th, rss, res.shape[0] / colour, jnp.sum(active[-k:]), sol.num_steps, sol.successful


_optimised_row = quick_jit(_fit_row, options=SOLVE_OFTEN)
_quick_row = quick_jit(_fit_row)


def _colour_factor(res: Float[Array, "N k"]) -> Float[Array, ""]:
    """``(1 + r1) / (1 - r1)`` of the lag-1 autocorrelation ``r1`` (mean over channels, clipped to [0, 0.99])."""
    r1 = jnp.sum(res[1:] * res[:-1], axis=0) / jnp.maximum(jnp.sum(res**2, axis=0), 1e-300)
    r1 = jnp.clip(jnp.mean(r1), 0.0, 0.99)
    return (1.0 + r1) / (1.0 - r1)


SCORE_WIDTH = 8
"""Pairs :func:`score` evaluates in one call: one compiled program for the diagnosis's stages, which score different
numbers of pairs."""


def score(
    pred: Predictor, thetas: Float[Array, "C 40"], etas: Float[Array, "C E"]
) -> tuple[Float[Array, "C k"], Float[Array, "C S"]]:
    """Gap per channel (:func:`jaxheli.cost.nmse`) and residual energy per significance window of each
    ``(theta, eta)`` pair (the bias states in the filter only where a walk is not zero), :data:`SCORE_WIDTH` pairs at
    a time (the last group padded with copies of the last pair): one compiled program for any number of pairs."""
    pred = pred.for_walks(np.any(np.asarray(etas)[:, _walk_slots(pred.outputs)]))
    count = thetas.shape[0]
    padded = [np.concatenate([a, np.repeat(a[-1:], -count % SCORE_WIDTH, axis=0)])
              for a in map(np.asarray, (thetas, etas))]
    groups = [_score(pred, *(a[i : i + SCORE_WIDTH] for a in padded)) for i in range(0, count, SCORE_WIDTH)]
    return tuple(jnp.asarray(np.concatenate([np.asarray(g) for g in parts])[:count]) for parts in zip(*groups))


@eqx.filter_jit
def _score(
    pred: Predictor, thetas: Float[Array, "C 40"], etas: Float[Array, "C E"]
) -> tuple[Float[Array, "C k"], Float[Array, "C S"]]:
    y = jax.vmap(pred)(thetas, etas)
    return nmse(y, pred.measured), pred.segment_energy(y)
