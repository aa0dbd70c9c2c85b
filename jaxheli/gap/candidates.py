"""The candidate rows of the effect diagnosis: each fitted on the training flight jointly with the base model (or on
the frozen base), scored on the validation flight, the best of its starts kept, the reference challenged by the
candidates' base parameters, and every candidate credited and ranked against the better model without an effect.

A batch of rows (:class:`~jaxheli.gap.fit_effect.EffectRows`, row 0 the reference: the base model re-fitted alone,
:mod:`jaxheli.gap.reference`) goes through :func:`fit_and_score` (fit, score, keep a start per candidate, challenge,
follow) and :func:`ranked` (credit against :func:`~jaxheli.gap.significance.yardstick`, test significance, rank).
The rows' arrays come from the catalogue of effects (:func:`~jaxheli.effects.registry.candidate_arrays`,
:func:`~jaxheli.effects.registry.tried_arrays`)."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._progress import note, stage
from .._types import ArrayLike, Float
from ..bounds import Bounds
from ..effects import registry as fx
from ..effects.plant import no_effect
from .candidate_records import Entry, Refit
from .fit_effect import EffectRows, embed, fit_candidates, score, with_reference
from .predictor import Predictor
from .reference import REFERENCE_STEPS, Scored, base_refit, carry_reference, refit_alone, withhold
from .significance import HeldOut, shrink_entries, yardstick
from .thresholds import THRESHOLDS

CHALLENGERS = 3
"""Most candidates whose base parameters the reference is re-fitted from (:func:`challenge`)."""

START_TIE_PCT = THRESHOLDS.start_tie_pct
"""Training-RSS difference (%) within which two starts of one candidate fit equally well (:func:`best_rows`)."""


def fit_and_score(
    train: Predictor, validate: Predictor, theta: Float[ArrayLike, "40"], cand: EffectRows, max_steps: int,
    box: Bounds | None, owner: np.ndarray | None = None, challengers: int = 0,
) -> Scored:
    """Fit the rows of ``cand`` (row 0 the reference, :func:`~jaxheli.gap.fit_effect.with_reference`) on
    ``train`` and score them and the given base ``theta`` on ``validate``. Jointly re-identified in ``box`` when
    given, in two stages: the reference first (up to :data:`~jaxheli.gap.reference.REFERENCE_ROUNDS` rounds of
    :data:`~jaxheli.gap.reference.REFERENCE_STEPS` budgets), then every row, the reference again among them, from
    its optimum (``rss_start``: the reference's training RSS there). With ``owner`` (the candidate each row after
    the reference fits, e.g. one row per start, :func:`~jaxheli.effects.registry.tried_arrays`) each candidate
    keeps its row of least training RSS (:func:`best_rows`): the rows returned are the reference's and one per
    candidate, in ``owner``'s numbering. Jointly, the first ``challengers`` candidates then challenge the reference
    (:func:`challenge`) and, when one moved it, every row is fitted again from there (:func:`follow`)."""
    base = jnp.asarray(no_effect(train.outputs))
    given = jnp.asarray(theta)
    start_theta, rss_start = given, None
    if box is not None:
        with stage(f"reference: the base model re-fitted alone ({REFERENCE_STEPS * max_steps} LM steps a round)"
                   ) as now:
            first = refit_alone(train, given, jax.tree.map(lambda a: a[:1], cand), REFERENCE_STEPS * max_steps, box)
            now.outcome = f"training RSS {float(first.rss[0]):.6g}"
        start_theta, rss_start = first.theta[0], float(first.rss[0])
        cand = carry_reference(cand, first.z[0])
    rows_in = cand.index.shape[0]
    with stage(f"fitting {rows_in - 1} candidate rows and the reference "
               + ("jointly with the base model" if box is not None else "on the frozen base model")
               + f" ({max_steps} LM steps, one solve)") as now:
        fit = fit_candidates(train, start_theta, base, cand, max_steps, box)
        etas = jax.vmap(lambda i, z: embed(base, i, z))(cand.index, fit.z)
        held = HeldOut(*(np.asarray(a) for a in score(validate, jnp.concatenate([given[None, :], fit.theta]),
                                                       jnp.concatenate([base[None, :], etas]))))
        now.outcome = f"training RSS: reference {float(fit.rss[0]):.6g}, best row {float(np.min(fit.rss)):.6g}"
    rows = held.take(slice(1, None))
    if owner is not None:
        neutral = np.r_[np.asarray(base), 0.0][np.asarray(cand.index)]
        size = np.sum(np.abs(np.asarray(fit.z) - neutral) / np.maximum(np.asarray(cand.upper - cand.lower), 1e-300),
                      axis=1)
        keep = best_rows(np.asarray(fit.rss), owner, size)
        fit, rows, cand = jax.tree.map(lambda a: a[keep], fit), rows.take(keep), jax.tree.map(lambda a: a[keep], cand)
    scored = Scored(fit, held.take(0), rows, rss_start)
    if box is not None and challengers:
        challenged = challenge(train, validate, cand, scored, REFERENCE_STEPS * max_steps, box, challengers)
        scored = follow(train, validate, cand, challenged, max_steps, box)
    return scored


def best_rows(rss: Float[np.ndarray, "R"], owner: np.ndarray, size: Float[np.ndarray, "R"] | None = None) -> np.ndarray:
    """Rows of a batched fit to keep: the reference (row 0), then for each candidate ``c`` the row among those
    ``owner`` gives it (``owner[r - 1]``, rows after the reference) of least training RSS ``rss``; with
    ``size`` (each row's fitted distance from no effect), the smallest among the rows within
    :data:`START_TIE_PCT` of that least RSS: starts that fit equally well are told apart by parsimony, not by
    the noise in their RSS."""
    rss, owner = np.asarray(rss)[1:], np.asarray(owner)
    size = rss if size is None else np.asarray(size)[1:]
    keep = [0]
    for c in range(int(owner.max()) + 1):
        rows = np.flatnonzero(owner == c)
        near = rows[rss[rows] <= np.min(rss[rows]) * (1.0 + START_TIE_PCT / 100.0)]
        keep.append(1 + int(near[np.argmin(size[near])]))
    return np.array(keep)


def challenge(
    train: Predictor, validate: Predictor, cand: EffectRows, scored: Scored, steps: int, box: Bounds, count: int,
) -> Scored:
    """The reference challenged by the candidates it would credit: the base model re-fitted alone (``steps`` LM
    steps) from the base parameters (and nuisance values) of each of the up to :data:`CHALLENGERS` of the first
    ``count`` candidates that shrink the held-out gap most (any positive shrink: below the noise floor too, their
    base parameters may have found the better basin). A joint fit can carry the base parameters into a better basin,
    and an effect is not paid for that: the re-fit of least training RSS, if below the reference's, replaces it (row
    0 of ``fit`` and ``rows``; ``rss_start`` moves by the same gain, so
    :func:`~jaxheli.gap.reference.base_refit`'s progress stays the reference's own)."""
    fit = scored.fit
    total = np.mean(scored.rows.gap, axis=1)
    shrink = 100.0 * (total[0] - total[1:count + 1]) / total[0]
    order = [c + 1 for c in np.argsort(-shrink) if shrink[c] > 0][:CHALLENGERS]
    base = jnp.asarray(no_effect(train.outputs))
    reference = jax.tree.map(lambda a: a[:1], cand)
    best = None
    for n, c in enumerate(order):
        with stage(f"challenge {n + 1} of {len(order)}: the reference re-fitted from row {c}'s base parameters") as now:
            start = carry_reference(dataclasses.replace(cand, start=fit.z), fit.z[c], row=c).start[:1]
            trial = refit_alone(train, fit.theta[c], dataclasses.replace(reference, start=start), steps, box)
            to_beat = float(fit.rss[0] if best is None else best.rss[0])
            if float(trial.rss[0]) < to_beat:
                best = trial
            now.outcome = (f"{'better' if best is trial else 'not better'}: training RSS {float(trial.rss[0]):.6g}, "
                           f"the reference's {to_beat:.6g}")
    if best is None:
        return scored
    gain = float(fit.rss[0] - best.rss[0])
    g, e = (np.asarray(a) for a in score(validate, best.theta, embed(base, reference.index[0], best.z[0])[None]))
    gap, energy = scored.rows.gap.copy(), scored.rows.energy.copy()
    gap[0], energy[0] = g[0], e[0]
    return Scored(jax.tree.map(lambda a, b: a.at[0].set(b[0]), fit, best), scored.given, HeldOut(gap, energy),
                  scored.rss_start - gain, moved=True)


def follow(train: Predictor, validate: Predictor, cand: EffectRows, after: Scored, steps: int, box: Bounds) -> Scored:
    """``after`` (the reference challenged, :func:`challenge`; its candidate rows as first fitted) with the candidates
    given the basin the reference moved to: when the challenge replaced the reference, every candidate row of ``cand``
    is fitted again (``steps`` LM steps) from the new reference's base parameters and nuisance values, its effect values
    started where its first fit ended, and keeps whichever of its two fits has the lower training RSS. A yardstick that
    escapes into a better basin while the candidates stay in the old one takes from every candidate the credit it had
    for its effect, and which candidate moved it decides the others' verdicts."""
    if not after.moved or cand.index.shape[0] < 2:
        return after
    base = jnp.asarray(no_effect(train.outputs))
    ref = jax.tree.map(lambda a: a[0], after.fit)
    rows = jax.tree.map(lambda a: a[1:], carry_reference(dataclasses.replace(cand, start=after.fit.z), ref.z))
    with stage(f"the {rows.index.shape[0]} candidate rows fitted again from the challenged reference's optimum "
               f"({steps} LM steps each)") as now:
        again = fit_candidates(train, ref.theta, base, rows, steps, box)
        better = np.asarray(again.rss) < np.asarray(after.fit.rss[1:])
        now.outcome = f"{int(np.sum(better))} of {better.size} rows fitted better"
    if not np.any(better):
        return after
    keep = jnp.asarray(np.r_[False, better])
    padded = jax.tree.map(lambda a, b: jnp.concatenate([a[:1], b]), after.fit, again)
    fit = jax.tree.map(lambda new, old: jnp.where(keep.reshape((-1,) + (1,) * (old.ndim - 1)), new, old), padded,
                       after.fit)
    etas = jax.vmap(lambda i, z: embed(base, i, z))(rows.index, again.z)
    g, e = (np.asarray(a) for a in score(validate, again.theta, etas))
    gap, energy = after.rows.gap.copy(), after.rows.energy.copy()
    gap[1:][better], energy[1:][better] = g[better], e[better]
    return after._replace(fit=fit, rows=HeldOut(gap, energy), followed=int(np.sum(better)))


class Ranked(NamedTuple):
    """Ranking entries, best first; the base model re-fitted alone (``None``: frozen base); the fits and scores
    behind them (:func:`fit_and_score`, rows after the candidates' included), the validation scores they were
    credited with (:func:`~jaxheli.gap.significance.yardstick`) and the reference's row as it started."""

    entries: list[Entry]
    refit: Refit | None
    scored: Scored
    credited: HeldOut
    reference: EffectRows


def ranked(
    train: Predictor, validate: Predictor, theta: Float[ArrayLike, "40"], labels: list[str],
    arrays: tuple[np.ndarray, ...], owner: np.ndarray | None, max_steps: int, min_shrink: float, box: Bounds | None,
    carried: Entry | None = None,
) -> Ranked:
    """Entries of the candidates ``labels`` whose ``(index, start, lower, upper)`` rows are ``arrays``
    (:func:`~jaxheli.effects.registry.candidate_arrays`, padded rows after them; with ``owner``, several rows per
    candidate and rows of further candidates after ``labels``', e.g. an oracle's), fitted behind the reference
    (:func:`fit_and_score`) and credited against the better model without an effect. Jointly (``box`` given), a
    ``carried`` entry's effect is freed in every row, the reference's included, started at its fitted values:
    the candidates are then credited beyond it."""
    outputs = train.outputs
    shared = box is not None
    values = None if carried is None else {**{n: e.value for n, e in carried.fitted.params.items()},
                                           **carried.nuisance}
    cand = with_reference(*arrays, len(no_effect(outputs)),
                          fx.nuisance_arrays(outputs, carried and carried.effect, values) if shared else None)
    scored = fit_and_score(train, validate, theta, cand, max_steps, box, owner, challengers=len(labels))
    rows = len(labels) + 1
    credited = yardstick(scored.given, scored.rows)
    ranking = shrink_entries(labels, outputs, jax.tree.map(lambda a: a[:rows], scored.fit),
                             credited.take(slice(None, rows)), min_shrink, shared)
    refit = base_refit(scored, outputs, min_shrink)
    entries = withhold(ranking, refit)
    if entries:
        note(f"best so far: {entries[0].effect} shrinks the held-out gap {entries[0].shrink_pct:.1f} +- "
             f"{entries[0].shrink_se_pct:.1f} %; significant: "
             f"{', '.join(e.effect for e in entries if e.significant) or 'none'}")
    return Ranked(entries, refit, scored, credited, jax.tree.map(lambda a: a[:1], cand))
