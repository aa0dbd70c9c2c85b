"""Rank candidate effects by how far each shrinks the held-out gap, with a noise floor for significance.

Parsimony is validation-only scoring: every candidate is fitted on the training flight and scored on the
validation flight, so extra parameters earn nothing unless they predict new data. A candidate is
significant when its held-out shrink is at least ``min_shrink`` % (default 3 %): the noise floor, above the
largest shrink any candidate reached on the effect-free flights of the blind check
(``benchmarks/blind_diagnosis.py``), where a useless effect fitted to noise shrinks the held-out gap by
at most about 1 % and usually makes it worse. A candidate whose fitted parameters leave their physically
plausible range (:func:`jaxheli.effects.registry.implausible`, e.g. a 16 s "input delay") is never significant:
it shrinks the gap by absorbing something else; nor is one whose fitted size lies within two standard
errors of no effect (:data:`MIN_Z`). When none is, the verdict is "no significant effect".

Each entry also carries ``p_value``, a one-sided t-test over 0.5 s validation windows of the log ratio of
base to candidate residual energy (:func:`~jaxheli.gap.predictor.make_predictor`), as a second opinion.
It is not part of the verdict: an effect that acts only at large inputs (saturation, drag) concentrates
its gain in a few windows, and window tests then miss shrinks of 60-90 % that the blind check knows are
real."""

from __future__ import annotations

import dataclasses

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import scipy.stats

from .._types import ArrayLike, Float
from ..data.flight import FlightData
from ..problem import Problem
from ..model import G_SI
from ..effects import registry as fx
from ..effects.plant import no_effect
from .fit_effect import Fit, embed, fit_candidates, score
from .predictor import Predictor, make_predictor, tune_track

MIN_Z = 2.0
"""Smallest distance of a significant effect from no effect, in standard errors of its fitted size
(:func:`~jaxheli.effects.registry.evidence`): a shrink bought by parameters indistinguishable from zero (a
"2 +- 3 ms delay") is model error the fit absorbed, not the effect. Every correct attribution of the blind
check stands at 2.9 standard errors or more."""


def shrink_entries(
    names: list[str], outputs: tuple[str, ...], fit: Fit, gap_base: np.ndarray,
    gaps: np.ndarray, seg_base: np.ndarray, segs: np.ndarray, min_shrink: float,
) -> list[dict[str, Any]]:
    """Ranking entries ``{effect, where, params, shrink_pct, shrink_by_channel, significant, ...}``, best first.

    ``gap_base[k]``/``gaps[C, k]`` are validation gaps, ``seg_base[S]``/``segs[C, S]`` segment energies.
    """
    total_base = float(np.mean(gap_base))
    out = []
    for c, name in enumerate(names):
        parts = name.split("+")
        value = np.asarray(fit.z[c])
        stderr = np.asarray(fit.stderr[c])
        params, where, sentence, outside, offset, z = {}, [], [], [], 0, 0.0
        for part in parts:
            n = len(fx.params(part, outputs))
            p, w, s = fx.describe(part, outputs, value[offset:offset + n], stderr[offset:offset + n])
            params.update(p)
            where += w
            sentence.append(s)
            outside += fx.implausible(part, outputs, value[offset:offset + n])
            z = max(z, fx.evidence(part, outputs, value[offset:offset + n], stderr[offset:offset + n]))
            offset += n
        if outside:
            sentence.append("outside the physical range: " + ", ".join(outside))
        shrink = 100.0 * (total_base - float(np.mean(gaps[c]))) / total_base
        d = np.log(seg_base) - np.log(segs[c])
        p_value = float(scipy.stats.ttest_1samp(d, 0.0, alternative="greater").pvalue) if np.std(d) > 0 else 1.0
        out.append({
            "effect": name,
            "where": where,
            "params": params,
            "shrink_pct": shrink,
            "shrink_by_channel": {ch: 100.0 * float((gb - g) / gb) for ch, gb, g in zip(outputs, gap_base, gaps[c])},
            "significant": bool(shrink >= min_shrink and not outside and z >= MIN_Z),
            "plausible": not outside,
            "evidence_z": z,
            "p_value": p_value,
            "gap_base": total_base,
            "gap": float(np.mean(gaps[c])),
            "summary": "; ".join(sentence),
            "converged": bool(fit.converged[c]),
        })
    return sorted(out, key=lambda e: -e["shrink_pct"])


def _evaluate(
    train: Predictor, validate: Predictor, theta: Float[ArrayLike, "40"], names: list[str], combine: bool,
    max_steps: int, min_shrink: float, warm: np.ndarray | None = None, shape: tuple[int, int] | None = None,
) -> list[dict[str, Any]]:
    outputs = train.outputs
    index, start = fx.candidate_arrays(names, outputs, combine=combine, shape=shape)
    if warm is not None:
        start[:, : len(warm)] = warm
    base = jnp.asarray(no_effect(outputs))
    theta = jnp.asarray(theta)
    fit = fit_candidates(train, theta, base, jnp.asarray(index), jnp.asarray(start), max_steps)
    etas = jax.vmap(lambda i, z: embed(base, i, z))(jnp.asarray(index), fit.z)
    gaps, segs = (np.asarray(a) for a in score(validate, theta, jnp.concatenate([base[None, :], etas], axis=0)))
    labels = ["+".join(names)] if combine else list(names)
    n = len(labels) + 1
    return shrink_entries(labels, outputs, fit, gaps[0], gaps[1:n], segs[0], segs[1:n], min_shrink)


def rank_effects(
    base_theta: Float[ArrayLike, "40"],
    train: FlightData | Predictor,
    validate: FlightData | Predictor,
    effects: tuple[str, ...] | list[str] = fx.ALL,
    *,
    segment: float = 2.0,
    g: float = G_SI,
    max_steps: int = 40,
    min_shrink: float = 3.0,
    shape: tuple[int, int] | None = None,
    track: float | None = None,
) -> list[dict[str, Any]]:
    """Fit each effect on ``train`` (base ``theta`` fixed), score on ``validate``; ranking entries best first.

    ``segment`` (s) is the predictor's restart interval and ``track`` its restart filter's level (``None``:
    :func:`~jaxheli.gap.predictor.tune_track` on ``train``); ``min_shrink`` (%) the significance
    floor (see the module docstring); ``shape`` pads the batch of fits (:func:`~jaxheli.effects.registry.
    candidate_arrays`). Both flights must carry the same output channels; given as predictors
    (:func:`predictor_pair`), ``segment``, ``g`` and ``track`` are theirs.
    """
    train_pred, validate_pred = predictor_pair(base_theta, train, validate, segment=segment, g=g, track=track)
    return _evaluate(train_pred, validate_pred, base_theta, list(effects), False, max_steps, min_shrink, shape=shape)


def combine_effects(
    base_theta: Float[ArrayLike, "40"],
    train: FlightData | Predictor,
    validate: FlightData | Predictor,
    effects: tuple[str, ...] | list[str],
    *,
    segment: float = 2.0,
    g: float = G_SI,
    max_steps: int = 40,
    min_shrink: float = 3.0,
    ranking: list[dict[str, Any]] | None = None,
    shape: tuple[int, int] | None = None,
    track: float | None = None,
) -> dict[str, Any]:
    """The effects fitted jointly, one ranking entry named ``"a+b+..."``; with ``ranking`` (entries of
    :func:`rank_effects` for these effects) the joint fit starts from each effect's own fit; ``shape`` and
    ``track`` as in :func:`rank_effects`."""
    if not effects:
        raise ValueError("combine_effects: name at least one effect")
    train_pred, validate_pred = predictor_pair(base_theta, train, validate, segment=segment, g=g, track=track)
    warm = None
    if ranking is not None:
        fitted = {e["effect"]: e["params"] for e in ranking}
        warm = np.array([fitted[e][p.name]["value"] for e in effects for p in fx.params(e, train_pred.outputs)])
    return _evaluate(train_pred, validate_pred, base_theta, list(effects), True, max_steps, min_shrink, warm,
                     shape)[0]


def diagnose_effects(
    base_theta: Float[ArrayLike, "40"], train: FlightData | Predictor, validate: FlightData | Predictor,
    effects: tuple[str, ...] | list[str] = fx.ALL, *, top: int = 3, segment: float = 2.0, g: float = G_SI,
    track: float | None = None, **options,
) -> dict[str, Any]:
    """``{"ranking", "combination", "verdict", "track"}``: the ranking, the joint fit of the (up to ``top``)
    significant effects (``None`` unless two or more), a sentence, and the restart filter's level both used
    (tuned on ``train`` unless given). One predictor per flight (:func:`predictor_pair`) serves every fit.
    With ``top > 1`` the single fits are padded to the joint fit's width
    (:func:`~jaxheli.effects.registry.joint_shape`), so both run through one compiled solver; ``options``
    (``max_steps``, ``min_shrink``) go to :func:`rank_effects`."""
    train, validate = predictor_pair(base_theta, train, validate, segment=segment, g=g, track=track)
    shape = fx.joint_shape(effects, train.outputs, top) if top > 1 else None
    ranking = rank_effects(base_theta, train, validate, effects, shape=shape, **options)
    chosen = [e["effect"] for e in ranking if e["significant"]][:top]
    combination = (combine_effects(base_theta, train, validate, chosen, ranking=ranking, shape=shape, **options)
                   if len(chosen) > 1 else None)
    return {"ranking": ranking, "combination": combination, "verdict": verdict(ranking), "track": float(train.track)}


def verdict(ranking: list[dict[str, Any]]) -> str:
    """The best significant effect in words, or ``"no significant effect"``."""
    best = [e for e in ranking if e["significant"]]
    if not best:
        return "no significant effect"
    e = best[0]
    return f"{e['effect']} ({e['summary']}): gap shrinks {e['shrink_pct']:.1f} % on the validation flight"


def predictor_pair(
    theta: Float[ArrayLike, "40"], train: FlightData | Problem | Predictor, validate: FlightData | Problem | Predictor, *,
    segment: float = 2.0, g: float = G_SI, track: float | None = None,
) -> tuple[Predictor, Predictor]:
    """The predictors of the training and validation records (flights or problems), built once each
    (predictors are taken as they are): restarts every ``segment`` s, the restart filter at ``track`` (``None``: the level
    :func:`~jaxheli.gap.predictor.tune_track` picks for ``theta`` on ``train``)."""
    if isinstance(train, Predictor) and isinstance(validate, Predictor):
        return train, validate
    names = [x.outputs if isinstance(x, Problem) else x.output_names for x in (train, validate)]
    if names[0] != names[1]:
        raise ValueError(f"{validate.source}: output channels {names[1]} differ from the training "
                         f"flight's {names[0]} ({train.source})")
    train_pred = make_predictor(train, segment=segment, g=g)
    level = tune_track(train_pred, theta) if track is None else float(track)
    train_pred = dataclasses.replace(train_pred, track=jnp.asarray(level))
    return train_pred, make_predictor(validate, segment=segment, g=g, track=level)
