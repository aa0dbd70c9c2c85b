"""Rank candidate effects by how far each shrinks the held-out gap: the public API of the effect diagnosis.

Parsimony is validation-only scoring: every candidate is fitted on the training flight and scored on the validation
flight, so extra parameters earn nothing unless they predict new data. By default each candidate is fitted *jointly*
with the 40 base parameters (:func:`~jaxheli.gap.fit_effect.fit_candidates`), the way a user re-identifies a model,
and credited only against the **reference**: the base model re-fitted alone by the same solver, budget and start
(or the given base where that predicts the validation flight better, :func:`~jaxheli.gap.significance.yardstick`;
the reference and its challenges: :mod:`jaxheli.gap.reference`). Re-identified jointly, every fit, the reference's
included, also frees the nuisance parameters (:func:`~jaxheli.effects.registry.nuisance`: the restart filter's
level), so no candidate is paid for re-tuning the predictor. An effect whose size a fit from one start stops short
of (a tight saturation, a long lag) is fitted from further starts too (:func:`~jaxheli.effects.registry.start_rows`),
and the start of least *training* RSS is kept (:func:`~jaxheli.gap.candidates.best_rows`): the validation flight only
scores. Whether a shrink is significant: :mod:`jaxheli.gap.significance`. The candidate rows themselves (fit, score,
challenge, credit): :mod:`jaxheli.gap.candidates`; what the ranking adds up to: :mod:`jaxheli.gap.verdict`.

Every function here takes the two flights as predictors (:func:`predictor_pair`), built once with their restart
interval, gravity and restart-filter level."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .._progress import note, stage
from .._types import ArrayLike, Float
from ..bounds import Bounds
from ..data.flight import FlightData
from ..problem import Problem
from ..model import G_SI
from ..effects import registry as fx
from .candidate_records import Entry, Refit, Structure
from .candidates import Ranked, fit_and_score as fit_and_score, ranked
from .final_fit import final_fit
from .noise_last import beyond_noise, noise_beyond, padded_rows
from .fit_effect import MAX_STEPS
from .predictor import Predictor, make_predictor, tune_track
from .records import Attribution
from .reference import theta_box
from .significance import MIN_SHRINK
from .structure import physical_box, structure_hypothesis
from .thresholds import THRESHOLDS
from .verdict import NOISE, credited_past_noise, explains_more, find, named_entry, structure_leads as structure_leads


class Staged(NamedTuple):
    """The ranking and the base model's structure (:func:`staged`): ``ranked`` the ranking in the given box (an
    effect's significance as judged beyond the structure when it was re-checked, :data:`RECHECK`), ``refit`` the
    given base re-fitted alone in that box (``None``: frozen base), ``structure`` the hypothesis
    (:func:`~jaxheli.gap.structure.structure_hypothesis`), ``recheck`` the entries of the effects ranked again beyond
    the structure, in the physical ranges (:data:`RECHECK`; empty when not re-checked), the ``box`` the
    ranking kept the base parameters in, the entries of the effects ranked again beyond process noise when that
    leads the ranking (``beyond_noise``, :func:`~jaxheli.gap.noise_last.beyond_noise`; empty otherwise), and the
    noise's entries ranked beyond each other filtered disturbance, by its name (``noise_beyond``,
    :func:`~jaxheli.gap.noise_last.noise_beyond`; empty unless nothing was significant beyond the noise), and the
    re-check's whole ranking (``rechecked``: its fits and scores, further rows such as an oracle's included; ``None``
    when not re-checked)."""

    ranked: Ranked
    refit: Refit | None
    structure: Structure | None
    recheck: tuple[Entry, ...]
    box: Bounds | None
    beyond_noise: tuple[Entry, ...] = ()
    noise_beyond: Mapping[str, Entry] = MappingProxyType({})
    rechecked: Ranked | None = None


RECHECKS: tuple[str, ...] = ("significant", "all")
"""Which candidates :func:`staged` ranks again beyond a significant structure: those significant in the box, or every
one (:data:`RECHECK`)."""

RECHECK = THRESHOLDS.recheck
"""(Read from the thresholds file, :mod:`jaxheli.gap.thresholds`.) ``"significant"``: the effects significant in the
box are ranked again beyond the structure and stay significant where they are in both rankings; ``"all"``: every
candidate is, and is significant where it is beyond the structure (an effect the base model's box hid is credited
by what it explains beyond the widened base)."""

if RECHECK not in RECHECKS:
    raise ValueError(f"{THRESHOLDS.source}: unknown recheck {RECHECK!r}; rechecks are {RECHECKS}")


def _by_structure(
    train: Predictor, validate: Predictor, theta: Float[ArrayLike, "40"], labels: list[str],
    arrays: tuple[np.ndarray, ...], owner: np.ndarray, max_steps: int, min_shrink: float, box: Bounds | None,
) -> Staged:
    """The candidates ``labels`` (rows ``arrays``, candidate ``owner[r]`` for row ``r``; rows of further candidates
    after them, e.g. an oracle's, are fitted and scored too) ranked in ``box`` (:func:`ranked`), then, re-identified
    jointly, the base model's structure as the first hypothesis: its re-fit in the physical ranges. When that
    hypothesis is significant (the re-fit left the box and shrinks the gap), effects are ranked again from it, in
    those ranges (:data:`RECHECK`): under ``"all"`` every effect, significant where it is significant there, and
    only while the structure leads (:func:`structure_leads`); under ``"significant"`` the effects significant in the
    box, each staying significant only where it is in both rankings. Rows of further candidates are fitted and
    scored in the re-check too (no entry, no effect on the verdict). A real effect does not hinge on the base
    model's box, while one that stood in for a pinned or bounded parameter, or for the misfit of a base stuck in
    another optimum, changes with it. A re-fit that left the box without predicting the validation flight better
    says nothing against the box's ranking, and effects ranked again from it are judged from a worse base. An effect
    that shrinks the gap in the box at least as far as the structure does is not re-checked (:func:`explains_more`)."""
    first = ranked(train, validate, theta, labels, arrays, owner, max_steps, min_shrink, box)
    if box is None:
        return Staged(first, None, None, (), None)
    hypothesis = structure_hypothesis(train, validate, first.reference, first.scored, first.credited, box, max_steps,
                                      min_shrink)
    kept = {e.effect for e in first.entries if e.significant and explains_more(e, hypothesis)}
    every = RECHECK == "all"
    chosen = [c for c, name in enumerate(labels) if name not in kept
              and (every or any(e.significant and e.effect == name for e in first.entries))]
    idle = every and not structure_leads(first.entries, hypothesis)  # an effect outshrinks the structure
    if hypothesis is None or not hypothesis.significant or not chosen or idle:
        return Staged(first, first.refit, hypothesis, (), box)
    candidates = chosen + list(range(len(labels), int(owner.max()) + 1))  # ascending: further candidates last
    rows = padded_rows(owner, candidates)
    with stage(f"re-check of {', '.join(labels[c] for c in chosen)} beyond the structure, in the physical ranges"
               ) as now:
        again = ranked(train, validate, hypothesis.theta, [labels[c] for c in chosen], tuple(a[rows] for a in arrays),
                       np.searchsorted(candidates, owner[rows]), max_steps, min_shrink,
                       theta_box(hypothesis.theta, physical_box(box)))
        both = {e.effect for e in again.entries if e.significant}
        now.outcome = f"significant in both boxes: {', '.join(sorted(both)) or 'none'}"
    entries = [dataclasses.replace(e, significant=e.effect in kept or (e.effect in both and (every or e.significant)),
                                   tied_with=tuple(t for t in e.tied_with if t in both)) for e in first.entries]
    return Staged(first._replace(entries=entries), first.refit, hypothesis, tuple(again.entries), box,
                  rechecked=again)


def staged(
    train: Predictor, validate: Predictor, theta: Float[ArrayLike, "40"], labels: list[str],
    arrays: tuple[np.ndarray, ...], owner: np.ndarray, max_steps: int, min_shrink: float, box: Bounds | None,
) -> Staged:
    """The candidates ranked in the box and beyond the base model's structure (:func:`_by_structure`), and when
    the best significant effect is process noise, the effects the filter does not read ranked again beyond it
    (:func:`~jaxheli.gap.noise_last.beyond_noise`); when none is credited there, the noise ranked beyond each
    other filtered disturbance significant in the box (:func:`~jaxheli.gap.noise_last.noise_beyond`)."""
    stages = _by_structure(train, validate, theta, labels, arrays, owner, max_steps, min_shrink, box)
    entries = stages.ranked.entries
    best = next((e for e in entries if e.significant), None)
    if best is None or best.effect != NOISE or box is None:
        return stages
    again = beyond_noise(train, validate, labels, arrays, owner, best, max_steps, min_shrink, box)
    rivals = [e for e in entries if e.significant and e.effect != NOISE and fx.filtered(e.effect)]
    if any(credited_past_noise(e) for e in again) or not rivals:
        return stages._replace(beyond_noise=again)
    return stages._replace(beyond_noise=again, noise_beyond=noise_beyond(
        train, validate, labels, arrays, owner, rivals, max_steps, min_shrink, box))


def _rank(
    train: Predictor, validate: Predictor, theta: Float[ArrayLike, "40"], names: Sequence[str], max_steps: int,
    min_shrink: float, shape: tuple[int, int] | None, box: Bounds | None,
) -> Staged:
    """Each of the effects ``names`` fitted on its own, from each of its starts (:func:`staged`)."""
    *arrays, owner = fx.tried_arrays(list(names), train.outputs, shape=shape)
    return staged(train, validate, theta, list(names), tuple(arrays), owner, max_steps, min_shrink, box)


def _combine(
    train: Predictor, validate: Predictor, theta: Float[ArrayLike, "40"], names: Sequence[str], max_steps: int,
    min_shrink: float, warm: np.ndarray | None, shape: tuple[int, int] | None, box: Bounds | None,
) -> Entry:
    """The effects ``names`` fitted together, started at ``warm`` (their parameters in turn) when given."""
    index, start, lower, upper = fx.candidate_arrays(list(names), train.outputs, combine=True, shape=shape)
    if warm is not None:
        start[:, : len(warm)] = np.clip(warm, lower[:, : len(warm)], upper[:, : len(warm)])
    return ranked(train, validate, theta, ["+".join(names)], (index, start, lower, upper), None, max_steps,
                  min_shrink, box).entries[0]


def _warm(ranking: Sequence[Entry], effects: Sequence[str], outputs: tuple[str, ...]) -> np.ndarray:
    """The parameters of ``effects`` in turn, as their entries in ``ranking`` fitted them."""
    fitted = {e.effect: e.fitted.params for e in ranking}
    return np.array([fitted[e][p.name].value for e in effects for p in fx.params(e, outputs)])


def rank_effects(
    base_theta: Float[ArrayLike, "40"],
    train: Predictor,
    validate: Predictor,
    effects: Sequence[str] = fx.ALL,
    *,
    max_steps: int = MAX_STEPS,
    min_shrink: float = MIN_SHRINK,
    shape: tuple[int, int] | None = None,
    joint: bool = True,
    bounds: Bounds | None = None,
) -> list[Entry]:
    """Fit each effect on ``train``, score on ``validate`` (the flights' predictors, :func:`predictor_pair`);
    ranking entries best first.

    ``joint`` re-identifies the base parameters with each effect (and the reference alone) in ``bounds``
    (default: the authors' box, widened to hold ``base_theta``); ``joint=False`` holds them at
    ``base_theta``. ``min_shrink`` (%) is the significance floor (:mod:`~jaxheli.gap.significance`); ``shape``
    pads the batch of fits (:func:`~jaxheli.effects.registry.candidate_arrays`).
    """
    box = theta_box(base_theta, bounds) if joint else None
    return _rank(train, validate, base_theta, effects, max_steps, min_shrink, shape, box).ranked.entries


def combine_effects(
    base_theta: Float[ArrayLike, "40"],
    train: Predictor,
    validate: Predictor,
    effects: Sequence[str],
    *,
    max_steps: int = MAX_STEPS,
    min_shrink: float = MIN_SHRINK,
    ranking: Sequence[Entry] | None = None,
    shape: tuple[int, int] | None = None,
    joint: bool = True,
    bounds: Bounds | None = None,
) -> Entry:
    """The effects fitted jointly, one ranking entry named ``"a+b+..."``; with ``ranking`` (entries of
    :func:`rank_effects` for these effects) the joint fit starts from each effect's own fit; the rest as in
    :func:`rank_effects`."""
    if not effects:
        raise ValueError("combine_effects: name at least one effect")
    warm = None if ranking is None else _warm(ranking, effects, train.outputs)
    box = theta_box(base_theta, bounds) if joint else None
    return _combine(train, validate, base_theta, effects, max_steps, min_shrink, warm, shape, box)


def diagnose_effects(
    base_theta: Float[ArrayLike, "40"], train: Predictor, validate: Predictor, effects: Sequence[str] = fx.ALL, *,
    top: int = 3, joint: bool = True, bounds: Bounds | None = None, max_steps: int = MAX_STEPS,
    min_shrink: float = MIN_SHRINK,
) -> Attribution:
    """The ranking, the joint fit of the (up to ``top``) significant effects (``None`` unless two or more), the
    reference's shrink (:func:`~jaxheli.gap.reference.base_refit`; what they add up to: ``verdict``), the best
    significant effect's size re-identified on both flights (jointly only; :func:`~jaxheli.gap.final_fit.final_fit`),
    and the restart filter's level of the predictors ``train`` and ``validate`` (:func:`predictor_pair`). With
    ``top > 1`` the single fits are padded to the joint fit's width (:func:`~jaxheli.effects.registry.joint_shape`),
    so both run through one compiled solver; ``joint``, ``bounds``, ``max_steps`` and ``min_shrink`` as in
    :func:`rank_effects`."""
    shape = fx.joint_shape(effects, train.outputs, top) if top > 1 else None
    box = theta_box(base_theta, bounds) if joint else None
    note(f"ranking {len(effects)} candidate effect(s) on the validation flight"
         + (", each re-identified jointly with the base model" if joint else ", the base model frozen"))
    stages = _rank(train, validate, base_theta, effects, max_steps, min_shrink, shape, box)
    ranking, refit, structure = stages.ranked.entries, stages.refit, stages.structure
    chosen = [e.effect for e in ranking if e.significant][:top]
    combination = None
    if len(chosen) > 1:
        with stage(f"combination: {' + '.join(chosen)} fitted together") as now:
            combination = _combine(train, validate, base_theta, chosen, max_steps, min_shrink,
                                   _warm(ranking, chosen, train.outputs), shape, box)
            now.outcome = f"shrinks the held-out gap {combination.shrink_pct:.1f} %"
    verdict = find(ranking, refit, structure, stages.recheck, stages.beyond_noise, stages.noise_beyond)
    best = named_entry(verdict, ranking)
    final = None
    if best is not None and box is not None:
        with stage(f"final fit: {best.effect}'s size re-identified with the base model on both flights") as now:
            final = final_fit(train, validate, best, box)
            now.outcome = final.fitted.summary
    return Attribution(tuple(ranking), combination, refit, final, float(train.track), structure, stages.recheck,
                       stages.beyond_noise, dict(stages.noise_beyond))


def predictor_pair(
    theta: Float[ArrayLike, "40"], train: FlightData | Problem | Predictor, validate: FlightData | Problem | Predictor, *,
    segment: float, g: float = G_SI, track: float | None = None, smooth: bool = False,
) -> tuple[Predictor, Predictor]:
    """The predictors of the training and validation records (flights or problems), built once each
    (predictors are taken as they are, ``segment`` unused): restarts every ``segment`` s, the restart filter at ``track`` (``None``: the level
    :func:`~jaxheli.gap.predictor.tune_track` picks for ``theta`` on ``train``), each restart re-estimated from its
    segment's readings with ``smooth``
    (:func:`~jaxheli.gap.segment_restart.restart_correction`)."""
    if isinstance(train, Predictor) and isinstance(validate, Predictor):
        return train, validate
    names = [x.outputs if isinstance(x, Problem) else x.output_names for x in (train, validate)]
    if names[0] != names[1]:
        raise ValueError(f"{validate.source}: output channels {names[1]} differ from the training "
                         f"flight's {names[0]} ({train.source})")
    train_pred = make_predictor(train, segment=segment, g=g, smooth=smooth)
    level = tune_track(train_pred, theta) if track is None else float(track)
    train_pred = dataclasses.replace(train_pred, track=jnp.asarray(level))
    return train_pred, make_predictor(validate, segment=segment, g=g, track=level, smooth=smooth)
