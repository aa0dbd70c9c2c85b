"""Blind check of the effect diagnosis on piloted synthetic flights with one withheld effect (or none).

Each trial draws one effect kind at a random realistic magnitude (:func:`sample_injection`), flies a
training and a held-out validation flight of the truth plant carrying it (:func:`jaxheli.piloted_flight`
with ``effect=``; different excitations, independent noise), and diagnoses them without being told which.
Base model: the truth parameters with the effect withheld (honest about the effect, cheap, and it isolates
attribution from parameter-estimation error). Oracle: the truth with the true effect. All trials of a run
share flight length, so one compiled program, vmapped over flights and over candidates, fits and scores a
whole batch of trials at once.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from .._types import Array, Float
from ..synth.excitation import Excitation
from ..data.flight import FlightData
from ..model import TABLE2
from ..synth.piloted import DEFAULT_NOISE, DEFAULT_OUTPUTS, piloted_flight
from ..effects import registry as fx
from ..effects.catalogue import EFFECTS
from ..effects.plant import no_effect
from .fit_effect import Candidates, Fit, embed, fit_candidates, score, with_reference
from .predictor import Predictor, make_predictor, tune_track
from .ranking import shrink_entries

KINDS: tuple[str, ...] = fx.ALL + ("none",)
"""Effect kinds of the blind check: every candidate plus the effect-free control."""

TRAIN_EXCITATION = Excitation("mixed", amplitude=(0.2, 0.2, 0.2, 0.2), unit=0.15, band=(0.3, 3.0), fade=0.5)
VALIDATE_EXCITATION = Excitation("3211", amplitude=(0.25, 0.25, 0.25, 0.25), unit=0.35)


@dataclasses.dataclass(frozen=True)
class Injection:
    """A withheld effect: ``eta`` of the truth, gust std (m/s) and time constant (s), the primary parameter."""

    kind: str
    eta: np.ndarray
    gust: float
    gust_tau: float
    primary: str | None
    value: float


def sample_injection(kind: str, seed: int, outputs: tuple[str, ...] = DEFAULT_OUTPUTS,
                     duration: float = 30.0) -> Injection:
    """Draw ``kind`` at a random realistic magnitude by its registry entry's sampler (``numpy`` generator
    seeded by ``seed``; ranges in :mod:`jaxheli.effects.catalogue`) for a flight of ``duration`` s with the
    synthetic flights' measurement noise (:data:`~jaxheli.synth.piloted.DEFAULT_NOISE`)."""
    if kind not in KINDS:
        raise ValueError(f"sample_injection: unknown kind {kind!r}; kinds are {KINDS}")
    if kind == "none":
        return Injection(kind, no_effect(outputs), 0.0, 1.0, None, 0.0)
    eta, draw = EFFECTS.inject(kind, seed, outputs, DEFAULT_NOISE, duration)
    return Injection(kind, eta, float(draw.gust), float(draw.gust_tau), draw.primary, float(draw.values[draw.primary]))


def blind_flights(injection: Injection, seed: int, *, duration: float = 30.0, dt: float = 0.05,
                  outputs: tuple[str, ...] = DEFAULT_OUTPUTS) -> tuple[FlightData, FlightData]:
    """Training and validation flights (Table 2 truth plus ``injection``), seeds ``2 seed`` and ``2 seed + 1``."""
    common = dict(duration=duration, dt=dt, outputs=outputs, effect=injection.eta, gust=injection.gust,
                  gust_tau=injection.gust_tau)
    train = piloted_flight(TABLE2, excitation=TRAIN_EXCITATION, seed=2 * seed, **common)
    validate = piloted_flight(TABLE2, excitation=VALIDATE_EXCITATION, seed=2 * seed + 1, **common)
    return train, validate


def run_blind(
    trials: Sequence[tuple[str, int]],
    *,
    duration: float = 30.0,
    dt: float = 0.05,
    segment: float = 2.0,
    max_steps: int = 20,
    min_shrink: float = 3.0,
    batch: int = len(KINDS),
    on_batch: Callable[[list[dict[str, Any]]], None] | None = None,
) -> list[dict[str, Any]]:
    """Diagnose each ``(kind, seed)`` trial blind; one record per trial.

    ``batch`` flights at a time are fitted by one call (vmapped over flights and candidates; the last batch
    is padded by repeating its last trial, so every call has the same shapes and compiles once); a progress
    bar advances per batch and ``on_batch(records_so_far)`` runs after each, e.g. to save partial results.
    A record holds the injection, the verdict (``top``: best significant effect or ``"none"``), whether it
    is right, the fitted primary parameter of the true kind against its true value, the true kind's shrink
    (%) and the oracle's, the restart filter's level tuned on the training flight (``track``) and the full
    ranking.
    """
    outputs = DEFAULT_OUTPUTS
    injections = [sample_injection(kind, 7919 * seed + 101 * KINDS.index(kind), outputs, duration)
                  for kind, seed in trials]
    theta, base = jnp.asarray(TABLE2), jnp.asarray(no_effect(outputs))
    cand = with_reference(*fx.candidate_arrays(fx.ALL, outputs), pad=len(base))
    records = []
    for first in tqdm(range(0, len(trials), batch), desc="blind batches", unit="batch"):
        chunk = list(range(first, min(first + batch, len(trials))))
        padded = chunk + [chunk[-1]] * (batch - len(chunk))
        flights = [blind_flights(injections[i], 7919 * trials[i][1] + KINDS.index(trials[i][0]), duration=duration,
                                 dt=dt) for i in padded]
        tracks = [tune_track(make_predictor(t, segment=segment), theta) for t, _ in flights]
        train = _stack([make_predictor(t, segment=segment, track=k) for (t, _), k in zip(flights, tracks)])
        validate = _stack([make_predictor(v, segment=segment, track=k) for (_, v), k in zip(flights, tracks)])
        truth = jnp.asarray(np.stack([injections[i].eta for i in padded]))
        fits, gaps, segs = _fit_and_score(train, validate, truth, theta, base, cand, max_steps)
        for j, i in enumerate(chunk):
            fit = jax.tree.map(lambda a: a[j], fits)
            records.append(_record(injections[i], trials[i][1], fit, np.asarray(gaps[j]), np.asarray(segs[j]),
                                   min_shrink) | {"track": tracks[j]})
        if on_batch is not None:
            on_batch(records)
    return records


def _stack(predictors: list[Predictor]) -> Predictor:
    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *predictors)


@functools.partial(jax.jit, static_argnames=("max_steps",))
def _fit_and_score(
    train: Predictor, validate: Predictor, truth: Float[Array, "F E"], theta: Float[Array, "40"],
    base: Float[Array, "E"], cand: Candidates, max_steps: int,
) -> tuple[Fit, Float[Array, "F C+1 k"], Float[Array, "F C+1 S"]]:
    """Every flight's candidate fits on its training flight (the base model frozen; row 0 of ``cand`` the
    reference, no effect), then the validation gaps of the reference, each fitted candidate and the truth
    (oracle), all vmapped over flights ``F``."""

    def one(train, validate, eta_true):
        fit = fit_candidates(train, theta, base, cand, max_steps)
        etas = jax.vmap(lambda i, z: embed(base, i, z))(cand.index, fit.z)
        etas = jnp.concatenate([etas, eta_true[None, :]], axis=0)
        gaps, segs = score(validate, jnp.broadcast_to(theta, (etas.shape[0], theta.shape[0])), etas)
        return fit, gaps, segs

    return jax.vmap(one)(train, validate, truth)


def _record(inj: Injection, seed: int, fit, gaps, segs, min_shrink) -> dict[str, Any]:
    n = len(fx.ALL)
    ranking = shrink_entries(list(fx.ALL), DEFAULT_OUTPUTS, fit, gaps[:n + 1], segs[:n + 1], min_shrink)
    significant = [e["effect"] for e in ranking if e["significant"]]
    top = significant[0] if significant else "none"
    record = {"kind": inj.kind, "seed": int(seed), "top": top, "correct": top == inj.kind,
              "true_value": inj.value, "primary": inj.primary,
              "oracle_shrink_pct": 100.0 * (1.0 - float(np.mean(gaps[-1]) / np.mean(gaps[0]))),
              "ranking": ranking}
    if inj.primary is not None:
        entry = next(e for e in ranking if e["effect"] == inj.kind)
        estimate = entry["params"][inj.primary]["value"]
        record.update(estimate=estimate, stderr=entry["params"][inj.primary]["stderr"],
                      magnitude_error=abs(estimate - inj.value) / abs(inj.value), shrink_pct=entry["shrink_pct"])
    return record


DETECTABLE_PCT = 10.0
"""Oracle shrink (%) from which an injected effect counts as detectable: the truth model with the effect
shrinks the held-out gap of the base model by at least this much, well above the 3 % significance floor.
Below it the draw left the effect at the noise level of that flight (a bias the restarts absorb, a rotor
coupling the collective hardly excites), and no diagnosis can attribute what the data do not show."""


def summarise(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Per kind: trials, top-1 attribution %, median relative magnitude error, median shrink vs oracle %,
    and the top-1 % over the detectable trials (oracle shrink >= :data:`DETECTABLE_PCT`); plus the
    false-positive % on effect-free flights."""
    table = {}
    for kind in dict.fromkeys(r["kind"] for r in records):
        rs = [r for r in records if r["kind"] == kind]
        row = {"trials": len(rs), "top1_pct": 100.0 * float(np.mean([r["correct"] for r in rs]))}
        if kind != "none":
            seen = [r for r in rs if r["oracle_shrink_pct"] >= DETECTABLE_PCT]
            row["detectable_trials"] = len(seen)
            row["top1_detectable_pct"] = 100.0 * float(np.mean([r["correct"] for r in seen])) if seen else None
            row["magnitude_error_median"] = float(np.median([r["magnitude_error"] for r in rs]))
            row["shrink_vs_oracle_pct"] = float(np.median([100.0 * r["shrink_pct"] / r["oracle_shrink_pct"]
                                                           for r in rs]))
        table[kind] = row
    controls = [r for r in records if r["kind"] == "none"]
    fp = 100.0 * float(np.mean([r["top"] != "none" for r in controls])) if controls else float("nan")
    return {"kinds": table, "false_positive_pct": fp}


def markdown(summary: dict[str, Any]) -> str:
    """The summary as a markdown table."""
    lines = [f"| kind | trials | top-1 % | detectable (oracle shrink >= {DETECTABLE_PCT:g} %): trials, top-1 % "
             "| median magnitude error | median shrink vs oracle % |", "|---|---|---|---|---|---|"]
    for kind, row in summary["kinds"].items():
        err = f"{100 * row['magnitude_error_median']:.1f} %" if "magnitude_error_median" in row else "-"
        shrink = f"{row['shrink_vs_oracle_pct']:.1f}" if "shrink_vs_oracle_pct" in row else "-"
        seen = "-"
        if "detectable_trials" in row:
            pct = row["top1_detectable_pct"]
            seen = f"{row['detectable_trials']}, " + ("-" if pct is None else f"{pct:.0f}")
        lines.append(f"| {kind} | {row['trials']} | {row['top1_pct']:.0f} | {seen} | {err} | {shrink} |")
    lines.append(f"\nFalse positives on effect-free flights: {summary['false_positive_pct']:.0f} %")
    return "\n".join(lines)


def run_benchmark(kinds: Sequence[str], seeds: int, out: str | Path, **options) -> dict[str, Any]:
    """Run ``seeds`` blind trials per kind; write ``OUT/blind.json`` (records, summary) and ``OUT/blind.md``."""
    bad = [k for k in kinds if k not in KINDS]
    if bad:
        raise ValueError(f"blind benchmark: unknown kinds {bad}; kinds are {KINDS}")
    t0 = time.perf_counter()
    settings = {"kinds": list(kinds), "seeds": seeds, **options,
                "base_model": "truth parameters (Table 2) with the effect withheld"}
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    def save(records: list[dict[str, Any]]) -> dict[str, Any]:
        summary = summarise(records)
        summary["runtime_s"] = time.perf_counter() - t0
        summary["settings"] = settings
        summary["complete"] = len(records) == len(kinds) * seeds
        (out / "blind.json").write_text(json.dumps({"summary": summary, "records": records}, indent=2))
        (out / "blind.md").write_text(markdown(summary) + f"\n\nRuntime {summary['runtime_s']:.0f} s.\n")
        return summary

    records = run_blind([(k, s) for s in range(seeds) for k in kinds], on_batch=save, **options)
    summary = save(records)
    return summary
