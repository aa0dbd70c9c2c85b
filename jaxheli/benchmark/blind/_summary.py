"""A blind run's statistics: which trials count in each subset (detectable, resolvable, resolvable beyond the
structure, identifiable, explainable), per-kind rates and median magnitude errors, the false-positive rate with its
Wilson interval, and other base methods set beside PEM on the same trials."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import scipy.stats

from ...gap.significance import MIN_SHRINK, MIN_Z
from ..truth import IN_FAMILY, KIND_CANDIDATES


def identifiable(record: dict[str, Any]) -> bool:
    """A detectable trial (:func:`detectable`) whose *training* flight resolves the effect: the oracle's fitted
    size stands :data:`~jaxheli.gap.significance.MIN_Z` standard errors or more from no effect
    (:func:`~jaxheli.effects.registry.evidence`), the test every significant candidate must pass. The validation
    flight's 3-2-1-1 sticks (0.25) are larger than a regulating pilot's (about 0.08 at most), so an effect that only
    large sticks reach (a saturation at 0.15-0.3 stick) can shrink the held-out gap once its true size is handed in
    while the training flight cannot tell it from none (``docs/blind_history.md``)."""
    z = record.get("oracle_evidence_z")
    return detectable(record) and z is not None and z >= MIN_Z


def explainable(record: dict[str, Any]) -> bool:
    """A detectable trial (:func:`detectable`) whose oracle, the right candidate fitted where the effect acts,
    shrinks the validation gap by :data:`~jaxheli.gap.significance.MIN_SHRINK` % or more: the trials any rule on
    the catalogue's forms could credit. A diagnostic of where misses come from (the form, or the rules), not a
    subset to score on: it hinges on the method's fit and floor."""
    return detectable(record) and record.get("oracle_shrink_pct", -np.inf) >= MIN_SHRINK


def explainable_beyond_structure(record: dict[str, Any]) -> bool:
    """An explainable trial (:func:`explainable`) whose oracle, where effects were ranked again beyond the base
    model's structure (:func:`~jaxheli.gap.ranking.staged`), shrinks the gap by :data:`MIN_SHRINK` % or more there
    too: what a verdict that names the structure first could still credit. Like :func:`explainable`, a diagnostic
    of where misses come from, not a subset to score on."""
    beyond = record.get("oracle_beyond_structure_pct")
    return explainable(record) and (beyond is None or beyond >= MIN_SHRINK)


def detectable(record: dict[str, Any]) -> bool:
    """Whether the trial's effect is detectable at all, as its truth simulator decided before any fit and apart
    from any method: it moves some noise-free validation output by more than that channel's sensor noise
    (``max_k rms_t(y_eff - y_clean) / sigma_k > 1``, :func:`~jaxheli.benchmark.truth.detectability_ratio`)."""
    return bool(record["detectable"])


def resolvable(record: dict[str, Any]) -> bool:
    """A detectable trial (:func:`detectable`) whose *training* flight shows the effect too, decided by its truth
    simulator the same way (:mod:`jaxheli.benchmark.truth`; ``False`` in records written before the training flight
    was scored): the trials the data can resolve, since the diagnosis learns each candidate from the training
    flight and only scores it on the validation flight."""
    return detectable(record) and bool(record.get("resolvable", False))


def beyond_structure(record: dict[str, Any]) -> bool:
    """A resolvable trial (:func:`resolvable`) whose effect a hover model alone cannot take up: the 40 parameters
    fitted in the physical ranges to the noise-free training flight leave more than the sensor noise of the
    effect on the noise-free validation flight (``structure_reach`` > 1,
    :func:`~jaxheli.benchmark.structure_reach.structure_reach`), decided by the truth simulator apart from any
    method's fit to the noisy flights. Where it is not, the flights cannot tell the effect from another hover model, so
    a verdict of the base model's structure is all the data support. ``False`` in records without the measure."""
    reach = record.get("structure_reach")
    return resolvable(record) and reach is not None and reach > 1.0


def _pct(flags: list[bool]) -> float | None:
    return 100.0 * float(np.mean(flags)) if flags else None


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def _subset(rows: list[dict[str, Any]], label: str) -> dict[str, Any]:
    """Trials, top-1 %, in-tie-set % and median magnitude error (the diagnosis's, its training fit's and the
    oracle's) of ``rows``, keys suffixed ``label``."""
    return {f"{label}_trials": len(rows), f"top1_{label}_pct": _pct([r["correct"] for r in rows]),
            f"in_tie_{label}_pct": _pct([r.get("in_tie", r["correct"]) for r in rows]),
            f"magnitude_error_median_{label}": _median([r["magnitude_error"] for r in rows if "magnitude_error" in r]),
            f"train_magnitude_error_median_{label}": _median([r["magnitude_error_train"] for r in rows
                                                               if "magnitude_error_train" in r]),
            f"oracle_magnitude_error_median_{label}": _median([r["oracle_magnitude_error"] for r in rows
                                                                if "oracle_magnitude_error" in r])}


def summarise(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Per kind: trials, top-1 % and in-tie-set %, over all trials, over the detectable ones (:func:`detectable`),
    the resolvable ones (:func:`resolvable`), those resolvable beyond the structure where the records have it
    (:func:`beyond_structure`) and the identifiable ones (:func:`identifiable`), with the median relative
    magnitude error of each subset (the diagnosis's, its training fit's and the oracle's; a trial whose verdict does
    not name its effect counts its training fit's, so the detectable ones' are also given over the trials named right
    alone, ``magnitude_error_median_named``), and the median shrink
    vs oracle % (detectable), and the % of trials whose verdict names the base model's structure
    (:mod:`jaxheli.gap.structure`), and the explainable trials (:func:`explainable`) and those explainable beyond
    the structure (:func:`explainable_beyond_structure`) with their top-1 %; plus the false-positive % on
    effect-free flights."""
    table = {}
    for kind in dict.fromkeys(r["kind"] for r in records):
        rs = [r for r in records if r["kind"] == kind]
        row = {"trials": len(rs), "top1_pct": _pct([r["correct"] for r in rs]),
               "in_tie_pct": _pct([r.get("in_tie", r["correct"]) for r in rs]),
               "structure_pct": _pct([r.get("structure_named", False) for r in rs])}
        if kind != "none":
            seen = [r for r in rs if detectable(r)]
            row.update(_subset(seen, "detectable"))
            row["magnitude_error_median_named"] = _median([r["magnitude_error"] for r in seen
                                                           if r["correct"] and "magnitude_error" in r])
            row.update(_subset([r for r in seen if resolvable(r)], "resolvable"))
            if any("structure_reach" in r for r in rs):
                row.update(_subset([r for r in seen if beyond_structure(r)], "beyond_structure"))
            row.update(_subset([r for r in seen if identifiable(r)], "identifiable"))
            reach = [r for r in seen if explainable(r)]
            row.update(explainable_trials=len(reach), top1_explainable_pct=_pct([r["correct"] for r in reach]))
            past = [r for r in seen if explainable_beyond_structure(r)]
            row.update(explainable_beyond_structure_trials=len(past),
                       top1_explainable_beyond_structure_pct=_pct([r["correct"] for r in past]))
            shrunk = [100.0 * r["shrink_pct"] / r["oracle_shrink_pct"] for r in seen if "shrink_pct" in r]
            row["shrink_vs_oracle_pct"] = float(np.median(shrunk)) if shrunk else None
        table[kind] = row
    controls = [r for r in records if r["kind"] == "none"]
    named = [r["top"] != "none" for r in controls]
    return {"kinds": table, "forms": forms(records), "false_positive_pct": _pct(named),
            "false_positives": sum(named), "controls": len(controls),
            "false_positive_ci95_pct": wilson_interval(sum(named), len(controls)) if controls else None}


def forms(records: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Top-1 pooled over the independent simulator's effect trials by form: ``in-family`` (the kinds of
    :data:`~jaxheli.benchmark.truth.IN_FAMILY`, whose nearest candidate comes within the noise) and ``other forms``
    (every other kind that a candidate counts as naming, ``two_at_once`` included), over all trials, over the
    resolvable ones (:func:`resolvable`), over the resolvable ones whose oracle explains the effect, beyond the
    structure where the effects were ranked again there (:func:`explainable_beyond_structure`: what any rule on the
    catalogue's forms could credit, a diagnostic of where misses come from) and, where the records have it, over
    those resolvable beyond the structure (:func:`beyond_structure`)."""
    pools = {"in-family": lambda k: k in IN_FAMILY,
             "other forms": lambda k: k not in IN_FAMILY and k in KIND_CANDIDATES and KIND_CANDIDATES[k] != ("none",)}
    out = {}
    for label, member in pools.items():
        rows = [r for r in records if r.get("truth_sim") == "independent" and member(r["kind"])]
        if rows:
            seen = [r for r in rows if resolvable(r)]
            past = [r for r in seen if explainable_beyond_structure(r)]
            out[label] = {"trials": len(rows), "top1_pct": _pct([r["correct"] for r in rows]),
                          **_subset(seen, "resolvable"), "resolvable_explainable_trials": len(past),
                          "top1_resolvable_explainable_pct": _pct([r["correct"] for r in past])}
            if any("structure_reach" in r for r in rows):
                out[label].update(_subset([r for r in rows if beyond_structure(r)], "beyond_structure"))
    return out


def wilson_interval(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson score interval (%) of a rate seen ``k`` times in ``n`` trials (scipy's ``binomtest``): what ``n``
    controls can say about a false-positive rate (6 of 40: 7-29 %; 0 of 40: 0-9 %)."""
    ci = scipy.stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    return 100.0 * float(ci.low), 100.0 * float(ci.high)


def summarise_bases(records: list[dict[str, Any]]) -> dict[str, Any]:
    """:func:`summarise` of the trials of the run's main base method (its first record's, ``"base"``), with
    ``"bases"``: for every other base method that ran, its summary and the main base's summary of the same trials
    (kind and seed), side by side."""
    main = records[0]["base"]["method"] if records else "pem"
    main_rows = [r for r in records if r["base"]["method"] == main]
    summary = summarise(main_rows)
    summary["base"], summary["bases"] = main, {}
    for method in dict.fromkeys(r["base"]["method"] for r in records if r["base"]["method"] != main):
        rows = [r for r in records if r["base"]["method"] == method]
        same = {(r["kind"], r["seed"]) for r in rows}
        seeds = sorted({r["seed"] for r in rows})
        summary["bases"][method] = {"seeds": f"{seeds[0]}-{seeds[-1]}", method: summarise(rows),
                                    main: summarise([r for r in main_rows if (r["kind"], r["seed"]) in same])}
    return summary


def summarise_records(path: str | Path) -> dict[str, Any]:
    """:func:`summarise_bases` of the records in an earlier run's ``blind.json`` (``path``); a file without records
    is an error naming it."""
    try:
        records = json.loads(Path(path).read_text())["records"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{path}: not a blind run's records ({err!r})") from err
    return summarise_bases(records)
