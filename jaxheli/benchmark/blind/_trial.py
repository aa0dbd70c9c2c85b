"""One blind trial: its flights, the base model identified on the training flight, the joint diagnosis and the
oracle (the true effect started at its true values and fitted the same way), and the record of what it found."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..._progress import stage
from ...bounds import Bounds
from ...data.flight import constant_outputs
from ...effects import registry as fx
from ...gap.final_fit import final_fit
from ...gap.fit_effect import MAX_STEPS
from ...gap.predictor import RESTART, SEGMENT, smooths
from ...gap.candidates import Ranked
from ...gap.ranking import predictor_pair, staged, structure_leads
from ...gap.verdict import find, named_entry
from ...gap.records import Entry, Final, Refit, Structure
from ...gap.reference import theta_box
from ...gap.significance import MIN_SHRINK
from ...synth.piloted import DEFAULT_OUTPUTS
from ._base import base_model
from ._flights import trial_flights
from ._injection import Injection, _restrict
from ._scenario import BOXES, scenario


class Trial(NamedTuple):
    """One blind trial: effect kind, seed and base-model method (:data:`BASES`)."""

    kind: str
    seed: int
    base: str = "pem"


def run_trial(
    kind: str, seed: int, *, base: str = "pem", truth: str = "library", duration: float = 30.0, dt: float = 0.05,
    segment: float = SEGMENT, max_steps: int = MAX_STEPS, pem_steps: int = 100, iterations: int = 1000,
    min_shrink: float = MIN_SHRINK, box: str = "hull", restart: str = RESTART, truths: str = "narrow",
) -> dict[str, Any]:
    """One blind trial: scenario and injection of ``seed``, flights, base model identified on the training
    flight by ``base`` (:func:`base_model`), joint diagnosis and oracle; the record (verdict, attribution, shrinks,
    ranking, the named effect's :func:`~jaxheli.gap.final_fit.final_fit`), flown by the ``truth`` simulator
    (:func:`trial_flights`; ``correct`` when the top candidate is one of the kinds that count as right). The
    magnitude is the one the diagnosis reports for the true kind (the oracle's): re-identified on both flights
    where it is the named effect, else its training fit (``estimate``, ``magnitude_error``); beside it the training
    fit's (``estimate_train``, ``magnitude_error_train``) and the oracle's (``oracle_estimate``,
    ``oracle_magnitude_error``). The truth is of the class ``truths`` (:data:`TRUTH_CLASSES`). The base model is
    identified, and the diagnosis starts, in ``box``
    (:data:`BOXES`); the base model's structure is its first hypothesis (:func:`~jaxheli.gap.ranking.staged`).
    Every prediction restarts every ``segment`` s from the filter's state (``restart="filter"``) or from that
    state re-estimated by the segment's own readings
    (``"segment"``, :func:`~jaxheli.gap.segment_restart.restart_correction`;
    the defaults: the diagnosis's, :data:`~jaxheli.gap.predictor.RESTART`, :data:`~jaxheli.gap.predictor.SEGMENT`)."""
    if box not in BOXES:
        raise ValueError(f"blind trial: unknown box {box!r}; boxes are {tuple(BOXES)}")
    smooth = smooths(restart, "blind trial")
    where = scenario(seed, truths)
    inj, train, validate, right, facts = trial_flights(truth, kind, seed, where, duration=duration, dt=dt,
                                                       outputs=DEFAULT_OUTPUTS)
    flat = set(constant_outputs(train)) | set(constant_outputs(validate))
    outputs = tuple(c for c in DEFAULT_OUTPUTS if c not in flat)
    if flat:
        inj, train, validate = _restrict(inj, outputs), train.select(outputs), validate.select(outputs)
        facts = {**facts, "dropped_outputs": sorted(flat)}
    with stage(f"base model by {base} on the training flight"):
        theta, ident = base_model(train, base, seed, pem_steps=pem_steps, iterations=iterations, outputs=outputs,
                                  box=box)
    train_pred, validate_pred = predictor_pair(theta, train, validate, segment=segment, smooth=smooth)
    *arrays, owner = fx.tried_arrays(fx.ALL, outputs)
    oracle = _oracle_row(inj.kind, inj, *fx.candidate_arrays(fx.ALL, outputs))
    arrays = tuple(np.vstack([a, o]) for a, o in zip(arrays, oracle))
    stages = staged(train_pred, validate_pred, theta, list(fx.ALL), arrays, np.r_[owner, len(fx.ALL)], max_steps,
                    min_shrink, theta_box(theta, Bounds(*BOXES[box])))
    ranking, refit, structure = stages.ranked.entries, stages.refit, stages.structure
    scored = stages.ranked.scored
    verdict = find(ranking, refit, structure, stages.recheck, stages.beyond_noise, stages.noise_beyond)
    best = named_entry(verdict, ranking)
    final = None
    if best is not None:
        with stage(f"final fit: {best.effect}'s size re-identified with the base model on both flights"):
            final = final_fit(train_pred, validate_pred, best, stages.box)
    top = best.effect if best else "none"
    oracle_z, oracle_stderr = np.asarray(scored.fit.z[-1]), np.asarray(scored.fit.stderr[-1])
    record = {"kind": kind, "seed": int(seed), "truth_sim": truth, **facts, "truth": where.truth, "truth_class": truths,
              "style": where.style, "noise": where.noise, "strength": where.strength, "top": top,
              "correct": top in right,
              "in_tie": top in right or any(k in verdict.tied_with for k in right),
              "true_value": inj.value, "primary": inj.primary,
              "oracle_shrink_pct": _oracle_shrink(stages.ranked),
              "oracle_beyond_structure_pct": None if stages.rechecked is None else _oracle_shrink(stages.rechecked),
              "oracle_evidence_z": (fx.evidence(inj.kind, outputs, oracle_z, oracle_stderr)
                                    if inj.kind != "none" else None),
              "box": box, "restart": restart, "segment_s": segment, "base": ident, "base_refit": _untheta(refit),
              "structure": None if structure is None else _untheta(structure),
              "structure_named": structure_leads(ranking, structure),
              "recheck": [_untheta(e) for e in stages.recheck],
              "beyond_noise": [_untheta(e) for e in stages.beyond_noise],
              "noise_beyond": {k: _untheta(e) for k, e in stages.noise_beyond.items()},
              "track": float(train_pred.track),
              "ranking": [_untheta(e) for e in ranking], "final": None if final is None else _untheta(final)}
    if inj.primary is not None:
        entry = next(e for e in ranking if e.effect == inj.kind)
        trained = entry.fitted.params[inj.primary]
        reported = final.fitted.params[inj.primary] if top == inj.kind else trained
        oracle = fx.describe(inj.kind, outputs, oracle_z, oracle_stderr)[0][inj.primary].value
        record.update(estimate=reported.value, stderr=reported.stderr,
                      magnitude_error=_relative_error(reported.value, inj.value), estimate_train=trained.value,
                      magnitude_error_train=_relative_error(trained.value, inj.value),
                      shrink_pct=entry.shrink_pct,
                      oracle_estimate=oracle, oracle_magnitude_error=_relative_error(oracle, inj.value))
    return record


def _oracle_shrink(ranking: Ranked) -> float:
    """The oracle's held-out shrink (%) in ``ranking``: its last row against the reference it was credited by."""
    return 100.0 * (1.0 - float(np.mean(ranking.scored.rows.gap[-1]) / np.mean(ranking.credited.gap[0])))


def _untheta(result: Entry | Refit | Final | Structure) -> dict[str, Any]:
    """``result``'s JSON without its base parameters (a trial's record keeps the sizes, not 40 numbers each)."""
    return {k: v for k, v in result.to_json().items() if k != "theta"}


def _relative_error(value: float, true: float) -> float:
    return abs(value - true) / abs(true)


def _oracle_row(kind: str, inj: Injection, index, start, lower, upper) -> list[np.ndarray]:
    """The oracle's row of candidate arrays: the true kind started at its true values (``none``: no effect,
    every slot the padding)."""
    if kind == "none":
        return [np.full_like(index[:1], len(inj.eta))] + [np.zeros_like(a[:1]) for a in (start, lower, upper)]
    c = fx.ALL.index(kind)
    row = [a[c:c + 1].copy() for a in (index, start, lower, upper)]
    real = row[0][0] < len(inj.eta)
    row[1][0, real] = np.clip(inj.eta[row[0][0, real]], row[2][0, real], row[3][0, real])
    return row
