"""The base model's structure as the first hypothesis: before any unmodelled effect is credited, the base model is
re-fitted alone in the physical ranges (:data:`~jaxheli.model.WIDE_LOWER`, :data:`~jaxheli.model.WIDE_UPPER`), its
box's pinned parameters freed and its bounds widened.

A helicopter outside the identification box (Mettler's R-50 has ``Nw`` 2.8 where the authors' box pins ``Nw`` at 0,
and ``Mu``, ``Mv``, ``Nv`` beyond its bounds) leaves a gap that some candidate effect stands in for (a rotor-speed
coupling from collective to yaw rate for the missing ``Nw w``). The widened re-fit is scored on the validation flight
against the yardstick (:func:`~jaxheli.gap.significance.yardstick`) like a candidate; it is significant at a shrink of
``min_shrink`` % and :data:`~jaxheli.gap.significance.SIG_SIGMA` standard errors *and* when a parameter left the box:
a shrink without that is the box's own re-fit converging further, not its structure."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._progress import note, stage
from ..bounds import Bounds, physical_box
from ..effects.plant import no_effect
from ..model import PARAM_NAMES, WIDE_LOWER, WIDE_UPPER
from .fit_effect import EffectRows, embed, fitted_nuisance, score
from .predictor import Predictor
from .candidate_records import Structure
from .reference import REFERENCE_STEPS, Scored, refit_alone
from .significance import SIG_SIGMA, HeldOut, paired_se
from .thresholds import THRESHOLDS

LEFT_BOX = THRESHOLDS.left_box
"""Fraction of a parameter's physical range (:data:`~jaxheli.model.WIDE_LOWER` to
:data:`~jaxheli.model.WIDE_UPPER`) by which a widened re-fit must leave the box for that parameter to count as
freed or beyond its bound (a solver's last step across a bound is not structure)."""


def structure_hypothesis(
    train: Predictor, validate: Predictor, reference: EffectRows, scored: Scored, credited: HeldOut, box: Bounds,
    max_steps: int, min_shrink: float,
) -> Structure | None:
    """The reference of ``scored`` (its one row ``reference``, re-identified jointly in ``box``) re-fitted alone in
    :func:`physical_box` (the reference's budget, :data:`~jaxheli.gap.reference.REFERENCE_STEPS` times
    ``max_steps``) and scored against ``credited``'s row 0, the yardstick (:class:`~jaxheli.gap.records.Structure`);
    ``None`` when ``box`` already holds the physical ranges."""
    wide = physical_box(box)
    if wide is None:
        return None
    outputs = train.outputs
    base = jnp.asarray(no_effect(outputs))
    reference = dataclasses.replace(reference, start=scored.fit.z[:1])
    with stage(f"structure hypothesis: the reference re-fitted in the physical ranges ({REFERENCE_STEPS * max_steps} "
               "LM steps a round)"):
        fit = refit_alone(train, scored.fit.theta[0], reference, REFERENCE_STEPS * max_steps, wide)
        gap, energy = (np.asarray(a)[0] for a in score(validate, fit.theta, embed(base, reference.index[0],
                                                                                     fit.z[0])[None]))
    yard = credited.take(0)
    gap_yard = float(np.mean(yard.gap))
    shrink = 100.0 * (gap_yard - float(np.mean(gap))) / gap_yard
    se = paired_se(yard.energy, energy, float(np.sum(yard.energy)))
    theta = np.asarray(fit.theta[0], np.float64)
    lower, upper = np.asarray(box.lower, np.float64), np.asarray(box.upper, np.float64)
    tol = LEFT_BOX * (WIDE_UPPER - WIDE_LOWER)
    below, above = theta < lower - tol, theta > upper + tol
    pinned = lower == upper
    freed = {n: float(v) for n, v, p, out in zip(PARAM_NAMES, theta, pinned, below | above) if p and out}
    beyond = {n: float(v) for n, v, p, out in zip(PARAM_NAMES, theta, pinned, below | above) if out and not p}
    crossed = {n: float(lower[i] if below[i] else upper[i]) for i, n in enumerate(PARAM_NAMES) if n in beyond}
    hypothesis = Structure(
        shrink_pct=shrink,
        shrink_se_pct=se,
        significant=bool((freed or beyond) and shrink >= min_shrink and shrink >= SIG_SIGMA * se),
        gap_base=gap_yard,
        gap=float(np.mean(gap)),
        gap_by_channel=dict(zip(outputs, map(float, gap))),
        freed=freed,
        beyond=beyond,
        crossed=crossed,
        theta=theta,
        nuisance=fitted_nuisance(np.asarray(fit.z[0]), outputs),
    )
    note(f"structure hypothesis: {hypothesis.summary}; shrinks the held-out gap {shrink:.1f} +- {se:.1f} % "
         f"({'significant' if hypothesis.significant else 'not significant'})")
    return hypothesis
