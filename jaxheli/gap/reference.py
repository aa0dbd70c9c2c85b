"""The yardstick every candidate effect is credited against: the base model re-fitted alone (the reference), and how
far it shrinks the given base's gap.

Fitting an effect on top of a frozen, under-fitted base pays the effect for whatever misfit its extra freedom soaks
up; the reference absorbs that first. The reference's own held-out shrink of the given base is reported
(:func:`base_refit`): beyond the noise, the base model is under-fitted and the verdict says so before any effect;
while the re-fitted base is still converging (:data:`SETTLED_PCT`), no effect is credited at all (:func:`withhold`).
A joint fit can also carry the base parameters into a better basin; the reference is then re-fitted from the
candidates' base parameters (:func:`~jaxheli.gap.candidates.challenge`), so that an effect is not paid for the
escape."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .._progress import note
from .._types import Array, ArrayLike, Float
from ..bounds import Bounds
from ..effects.plant import no_effect
from .fit_effect import EffectRows, EffectFit, fit_candidates, fitted_nuisance
from .predictor import Predictor
from .candidate_records import Entry, Refit
from .thresholds import THRESHOLDS
from .significance import SIG_SIGMA, HeldOut, paired_se

SETTLED_PCT = THRESHOLDS.settled_pct
"""Training-RSS decrease (%) of the reference over the candidates' step budget below which it counts as
settled. A reference still falling is no yardstick: every candidate's extra freedom buys more of the same
descent, so no effect is credited (:func:`withhold`)."""

REFERENCE_STEPS = 4
"""The base model re-fitted alone gets rounds of this many times the candidates' step budget before they start
from its optimum: credited against a reference that is still converging, an effect is paid for the solver's
progress."""

REFERENCE_ROUNDS = 3
"""Most rounds of the reference's own fit; it stops early once a round lowers its training RSS by less than
:data:`SETTLED_PCT` or the solver converges."""


class Scored(NamedTuple):
    """A batch of candidates fitted on the training flight and scored on the validation flight
    (:func:`~jaxheli.gap.candidates.fit_and_score`).

    Row 0 of ``fit`` and of ``rows`` is the reference, row ``c + 1`` the candidate ``c``; ``given`` scores the given
    base model; ``rss_start`` is the reference's training RSS where the candidates started (``None``: frozen base);
    ``moved``: a challenger's base parameters replaced the reference (:func:`~jaxheli.gap.candidates.challenge`);
    ``followed``: how many candidate rows then fitted better from its optimum (:func:`~jaxheli.gap.candidates.follow`).
    """

    fit: EffectFit
    given: HeldOut
    rows: HeldOut
    rss_start: float | None
    moved: bool = False
    followed: int = 0


def theta_box(theta: Float[ArrayLike, "40"], bounds: Bounds | None = None) -> Bounds:
    """The box a joint re-identification keeps the base parameters in: ``bounds`` (default: the authors'
    box), widened to contain ``theta``."""
    bounds = Bounds() if bounds is None else bounds
    theta = np.asarray(theta, np.float64)
    return Bounds(np.minimum(np.asarray(bounds.lower), theta), np.maximum(np.asarray(bounds.upper), theta))


def refit_alone(train: Predictor, theta: Float[Array, "40"], reference: EffectRows, steps: int, box: Bounds) -> EffectFit:
    """The base model fitted alone (``reference``: one row) from ``theta`` in up to :data:`REFERENCE_ROUNDS`
    rounds of ``steps`` LM steps, each from the last; it stops once a round lowers the training RSS by less
    than :data:`SETTLED_PCT` or the solver converges."""
    base = jnp.asarray(no_effect(train.outputs))
    fit = None
    for k in range(REFERENCE_ROUNDS):
        last = fit
        fit = fit_candidates(train, theta, base, reference, steps, box)
        note(f"  round {k + 1} of at most {REFERENCE_ROUNDS}: training RSS {float(fit.rss[0]):.6g} after "
             f"{int(fit.steps[0])} steps{' (converged)' if bool(fit.converged[0]) else ''}")
        theta, reference = fit.theta[0], dataclasses.replace(reference, start=fit.z)
        if bool(fit.converged[0]) or (last is not None and 100.0 * float(last.rss[0] - fit.rss[0])
                                      < SETTLED_PCT * float(last.rss[0])):
            break
    return fit


def carry_reference(cand: EffectRows, z: Float[ArrayLike, "K"], row: int = 0) -> EffectRows:
    """``cand`` with every row started where row ``row`` (the reference by default) ended in the slots it
    frees (``z``: its fitted values; e.g. nuisance parameters such as the restart filter's level)."""
    start = cand.start
    for j in range(cand.index.shape[1]):
        start = jnp.where(cand.index == cand.index[row, j], jnp.clip(z[j], cand.lower, cand.upper), start)
    return dataclasses.replace(cand, start=start)


def base_refit(scored: Scored, outputs: tuple[str, ...], min_shrink: float) -> Refit | None:
    """How far re-fitting the base model alone (the reference) shrinks the held-out gap of the given base
    (:class:`~jaxheli.gap.records.Refit`): under-fitted at a shrink of ``min_shrink`` % or more and
    :data:`~jaxheli.gap.significance.SIG_SIGMA` standard errors; settled when converged or its training RSS fell
    by less than :data:`SETTLED_PCT` from where the candidates started. ``None`` for a frozen base."""
    if scored.rss_start is None:
        return None
    fit, given, ref = scored.fit, scored.given, scored.rows.take(0)
    gap_given, gap_ref = float(np.mean(given.gap)), float(np.mean(ref.gap))
    progress = 100.0 * (scored.rss_start - float(fit.rss[0])) / scored.rss_start
    shrink = 100.0 * (gap_given - gap_ref) / gap_given
    se = paired_se(given.energy, ref.energy, float(np.sum(given.energy)))
    return Refit(
        shrink_pct=shrink,
        shrink_se_pct=se,
        gap_base=gap_given,
        gap=gap_ref,
        gap_by_channel=dict(zip(outputs, map(float, ref.gap))),
        under_fitted=bool(shrink >= min_shrink and shrink >= SIG_SIGMA * se),
        converged=bool(fit.converged[0]),
        progress_pct=progress,
        settled=bool(fit.converged[0]) or progress < SETTLED_PCT,
        steps=int(fit.steps[0]),
        theta=np.asarray(fit.theta[0], np.float64),
        nuisance=fitted_nuisance(np.asarray(fit.z[0]), outputs),
        challenged=scored.moved,
        followed=scored.followed,
    )


def withhold(ranking: list[Entry], refit: Refit | None) -> list[Entry]:
    """``ranking`` with no entry significant (nor tied) when the jointly re-fitted reference is not settled."""
    if refit is None or refit.settled:
        return ranking
    return [dataclasses.replace(e, significant=False, tied_with=()) for e in ranking]
