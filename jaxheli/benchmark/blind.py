"""Blind check of the effect diagnosis on piloted synthetic flights with one withheld effect (or none).

Each trial draws a scenario (:func:`scenario`: truth model, pilot/excitation style, sensor-noise level,
effect strength) and one effect kind at a random realistic magnitude (:func:`sample_injection`), flies a
training and a held-out validation flight of the truth plant carrying it (different excitations,
independent noise) and diagnoses them without being told which. The base model is what a user would have:
identified on the contaminated training flight (never the truth), in one box that covers both helicopter
classes (:data:`BOX`): by PEM, or by IWO and its gradient polish (:data:`BASES`, :func:`base_model`). The
diagnosis is the library's default: every candidate fitted jointly with the base parameters, credited beyond
the base re-fitted alone (:func:`~jaxheli.gap.ranking.fit_and_score`) or the given base, whichever predicts the
validation flight better (:func:`~jaxheli.gap.significance.yardstick`).
The oracle is the identified base with the *true* effect, started at its true values and fitted jointly the
same way; its own magnitude error shows how much of the diagnosis's is the identified base's. The named
effect's size is then re-identified on both flights (:func:`~jaxheli.gap.final_fit.final_fit`). All trials of
a run share the flight length, so each fit compiles once; candidates are fitted in one compiled solve, mapped
over them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any, NamedTuple

import jax
import numpy as np
import scipy.stats

from .._affinity import cores, on_core
from .._progress import left, note, stage
from ..bounds import Bounds
from ..data.flight import FlightData, constant_outputs
from ..effects import registry as fx
from ..effects.catalogue import EFFECTS
from ..effects.plant import no_effect
from ..identify import identify
from ..model import LOWER, R50_SI, TABLE2, UPPER
from ..optim.pem import pem
from ..synth.excitation import Excitation
from ..synth.piloted import DEFAULT_NOISE, DEFAULT_OUTPUTS, piloted_flight
from ..gap.final_fit import final_fit
from ..gap.fit_effect import MAX_STEPS
from ..gap.predictor import RESTART, SEGMENT, smooths
from ..gap.records import Entry, Final, Refit, Structure
from ..gap.ranking import predictor_pair, staged, structure_leads
from ..gap.reference import theta_box
from ..gap.significance import MIN_SHRINK, MIN_Z
from ..gap.thresholds import THRESHOLDS
from . import truth as independent_truth
from .independent import independent_trial

KINDS: tuple[str, ...] = fx.ALL + ("none",)
"""Effect kinds of the blind check: every candidate plus the effect-free control."""

STYLES: dict[str, Excitation] = {
    "doublets": Excitation("3211", amplitude=(0.2, 0.2, 0.2, 0.2), unit=0.3),
    "sweep": Excitation("sweep", amplitude=(0.15, 0.15, 0.15, 0.15), band=(0.3, 3.0), fade=0.5),
    "regulation": Excitation("mixed", amplitude=(0.04, 0.04, 0.04, 0.04), unit=0.15, band=(0.3, 3.0), fade=0.5),
}
"""Pilot/excitation styles of the training flight: 3-2-1-1 doublets, frequency sweeps, and the pilot
regulating hover with only faint stick excitation on top (the LQR pilot flies every style)."""

VALIDATE_EXCITATION = Excitation("3211", amplitude=(0.25, 0.25, 0.25, 0.25), unit=0.35)

TRUTHS: tuple[str, ...] = ("table2", "r50", "table2~", "r50~")
"""Truth models: the paper's Table 2 (TREX 550), Mettler's R-50 in SI, and each perturbed by up to +-30 %."""

NOISES: tuple[float, ...] = (1.0, 2.0)
"""Sensor-noise levels, multiples of :data:`~jaxheli.synth.piloted.DEFAULT_NOISE`."""

STRENGTHS: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0)
"""Effect strengths: the registry sampler's size parameters times these (time constants, which only shape an
effect, are not scaled), kept within 80 % of each parameter's physical bound."""


def _hull(*models: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = np.minimum.reduce([LOWER, *(np.minimum(0.5 * m, 2.0 * m) for m in models)])
    hi = np.maximum.reduce([UPPER, *(np.maximum(0.5 * m, 2.0 * m) for m in models)])
    return lo, hi


BOX = _hull(TABLE2, R50_SI)
"""``(lower, upper)``, the identification box of every trial by default: the authors' TREX box widened to hold half
to twice each Table 2 and R-50 parameter (so both classes, perturbed by 30 %, lie inside; ``Nw``, pinned in the TREX
box, is freed): what a user sets for a class of helicopter, not the truth."""

BOXES: dict[str, tuple[np.ndarray, np.ndarray]] = {"hull": BOX, "authors": (LOWER, UPPER)}
"""Identification boxes of the blind check: :data:`BOX` (``hull``), or the command line's default, the authors' TREX
box (``authors``), which the R-50 truths leave (``Mu``, ``Mv``, ``Nv`` beyond it, ``Nw`` pinned at 0): there the
diagnosis must name the base model's structure (:mod:`jaxheli.gap.structure`), not an effect."""


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A trial's truth model (name, parameters), training style, noise multiple and effect strength."""

    truth: str
    theta: np.ndarray
    style: str
    noise: float
    strength: float


def scenario(seed: int) -> Scenario:
    """The scenario of trial ``seed``: any 96 consecutive seeds meet every combination of :data:`TRUTHS`,
    :data:`STYLES`, :data:`NOISES` and :data:`STRENGTHS` once, and a few consecutive seeds already differ in all
    four (the combination index steps by 37, prime to 96); the perturbations of the ``~`` truths are drawn
    from ``seed`` (uniform factors 0.7-1.3)."""
    sizes = (len(TRUTHS), len(STYLES), len(NOISES), len(STRENGTHS))
    code = (37 * seed) % int(np.prod(sizes))
    i, j, k, m = (code // int(np.prod(sizes[:n])) % sizes[n] for n in range(4))
    truth = TRUTHS[i]
    theta = np.array(TABLE2 if truth.startswith("table2") else R50_SI)
    if truth.endswith("~"):
        theta = theta * np.random.default_rng(1_000_003 + seed).uniform(0.7, 1.3, theta.size)
    return Scenario(truth, theta, tuple(STYLES)[j], NOISES[k], STRENGTHS[m])


@dataclasses.dataclass(frozen=True)
class Injection:
    """A withheld effect: ``eta`` of the truth, gust std (m/s) and time constant (s), the primary parameter."""

    kind: str
    eta: np.ndarray
    gust: float
    gust_tau: float
    primary: str | None
    value: float


def sample_injection(kind: str, seed: int, outputs: tuple[str, ...] = DEFAULT_OUTPUTS, duration: float = 30.0,
                     strength: float = 1.0) -> Injection:
    """Draw ``kind`` at a random realistic magnitude by its registry entry's sampler (``numpy`` generator
    seeded by ``seed``; ranges in :mod:`jaxheli.effects.catalogue`) for a flight of ``duration`` s with the
    synthetic flights' measurement noise (:data:`~jaxheli.synth.piloted.DEFAULT_NOISE`), its size parameters
    (and wind) times ``strength``, each kept within 80 % of its physical bound (so none equals a fit's start: a
    saturation's further start is 90, :mod:`jaxheli.effects.catalogue`)."""
    if kind not in KINDS:
        raise ValueError(f"sample_injection: unknown kind {kind!r}; kinds are {KINDS}")
    if kind == "none":
        return Injection(kind, no_effect(outputs), 0.0, 1.0, None, 0.0)
    eta, draw = EFFECTS.inject(kind, seed, outputs, DEFAULT_NOISE, duration)
    for p in fx.params(kind, outputs):
        if p.name in draw.values and not p.shape:
            eta[p.slot] = np.clip(strength * eta[p.slot], -0.8 * p.bound, 0.8 * p.bound)
    primary = next(p for p in fx.params(kind, outputs) if p.name == draw.primary)
    return Injection(kind, eta, float(strength * draw.gust), float(draw.gust_tau), draw.primary,
                     float(eta[primary.slot]))


def blind_flights(injection: Injection, seed: int, where: Scenario, *, duration: float = 30.0, dt: float = 0.05,
                  outputs: tuple[str, ...] = DEFAULT_OUTPUTS) -> tuple[FlightData, FlightData]:
    """Training (``where``'s style) and validation flights of ``where``'s truth plus ``injection`` at its noise
    level, seeds ``2 seed`` and ``2 seed + 1``."""
    common = dict(duration=duration, dt=dt, outputs=outputs, effect=injection.eta, gust=injection.gust,
                  gust_tau=injection.gust_tau, noise=where.noise)
    train = piloted_flight(where.theta, excitation=STYLES[where.style], seed=2 * seed, **common)
    validate = piloted_flight(where.theta, excitation=VALIDATE_EXCITATION, seed=2 * seed + 1, **common)
    return train, validate


def _library_seeds(kind: str, seed: int) -> tuple[int, int]:
    """The library simulator's seeds of trial ``seed`` of ``kind``: its injection's and its flights'."""
    return 7919 * seed + 101 * KINDS.index(kind), 7919 * seed + KINDS.index(kind)


def _library_pair(injection: Injection, seed: int, where: Scenario, *, duration: float, dt: float,
                  outputs: tuple[str, ...], train: bool = False) -> tuple[FlightData, FlightData, np.ndarray]:
    """The library simulator's validation flight (``train``: its training flight; :func:`blind_flights`) flown
    noise-free with ``injection`` and again without it (same excitation and seed, the pilot's feedback re-flown), and
    the trial's sensor-noise std per output."""
    excitation, flight_seed = (STYLES[where.style], 2 * seed) if train else (VALIDATE_EXCITATION, 2 * seed + 1)
    common = dict(duration=duration, dt=dt, outputs=outputs, excitation=excitation, seed=flight_seed, noise=0.0)
    flown = piloted_flight(where.theta, effect=injection.eta, gust=injection.gust, gust_tau=injection.gust_tau,
                           **common)
    bare = piloted_flight(where.theta, **common)
    return flown, bare, np.array([where.noise * DEFAULT_NOISE[c] for c in outputs])


def _library_detectability(injection: Injection, seed: int, where: Scenario, *, duration: float, dt: float,
                           outputs: tuple[str, ...], train: bool = False) -> float:
    """The library simulator's detectability of ``injection``, decided before any fit: :func:`_library_pair` scored
    by :func:`~jaxheli.benchmark.truth.detectability_ratio` against the trial's sensor-noise std."""
    flown, bare, sigma = _library_pair(injection, seed, where, duration=duration, dt=dt, outputs=outputs, train=train)
    return independent_truth.detectability_ratio(flown.outputs, bare.outputs, sigma)


def noise_free_pair(truth: str, kind: str, seed: int, *, train: bool = False, duration: float = 30.0,
                    dt: float = 0.05, outputs: tuple[str, ...] = DEFAULT_OUTPUTS) -> tuple[tuple, tuple, np.ndarray]:
    """Trial ``seed`` of ``kind``'s validation flight (``train``: its training flight) by the ``truth`` simulator
    (:data:`TRUTHS_SIM`) as the blind check flies it, noise-free, with its effect and re-flown without it (each
    ``(time, sticks, readings)``), and the sensor-noise std per output: the pair its detectability compares."""
    where = scenario(seed)
    if truth == "independent":
        trial = independent_truth.truth_trial(kind, seed, where.theta, style=where.style, noise=where.noise,
                                              strength=where.strength, duration=duration, dt=dt, outputs=outputs)
        flown, style, flight_seed = ((trial.train, where.style, 2 * seed) if train
                                     else (trial.validate, independent_truth.VALIDATE_STYLE, 2 * seed + 1))
        clean = independent_truth.fly(where.theta, independent_truth.Effects(), style=style, duration=duration,
                                      dt=dt, seed=flight_seed, noise=trial.noise, outputs=outputs)
        return ((flown.time, flown.sticks, flown.clean), (clean.time, clean.sticks, clean.clean), trial.noise)
    injection_seed, flight_seed = _library_seeds(kind, seed)
    inj = sample_injection(kind, injection_seed, outputs, duration, where.strength)
    flown, bare, sigma = _library_pair(inj, flight_seed, where, duration=duration, dt=dt, outputs=outputs,
                                       train=train)
    return (flown.time, flown.inputs, flown.outputs), (bare.time, bare.inputs, bare.outputs), sigma


BASES: tuple[str, ...] = ("pem", "iwo+polish")
"""How a trial's base model is identified on its training flight: PEM (:func:`~jaxheli.optim.pem.pem`), or the
paper's IWO on the Pearson cost followed by the output-error polish (:func:`~jaxheli.identify.identify`)."""


class Trial(NamedTuple):
    """One blind trial: effect kind, seed and base-model method (:data:`BASES`)."""

    kind: str
    seed: int
    base: str = "pem"


def base_model(train: FlightData, method: str, seed: int, *, pem_steps: int = 100, iterations: int = 1000,
               outputs: tuple[str, ...] = DEFAULT_OUTPUTS, box: str = "hull") -> tuple[np.ndarray, dict[str, Any]]:
    """The base model a user identifies on ``train`` in the box ``box`` (:data:`BOXES`) by ``method``
    (:data:`BASES`): ``(theta, info)``, ``info`` the method and its run (PEM: ``pem_steps`` LM steps; IWO + polish:
    ``iterations`` generations seeded by ``seed``, then the polish)."""
    lower, upper = BOXES[box]
    if method == "pem":
        ident = pem(train, max_steps=pem_steps, outputs=outputs, lower=lower, upper=upper)
        return np.asarray(ident.theta), {"method": method, "steps": ident.n_steps, "success": ident.success,
                                         "rss": ident.rss}
    if method == "iwo+polish":
        ident = identify(train, method=method, iterations=iterations, seed=seed, outputs=outputs, lower=lower,
                         upper=upper, progress=False)
        return np.asarray(ident.params), {"method": method, "iterations": iterations, "seconds": ident.seconds,
                                          "search_cost": ident.polish["cost_after"],
                                          "polish_objective": ident.polish["objective_after"]}
    raise ValueError(f"blind trial: unknown base method {method!r}; methods are {BASES}")


TRUTHS_SIM: dict[str, tuple[str, ...]] = {"library": KINDS, "independent": independent_truth.KINDS}
"""Truth simulators of the blind check and the kinds each injects: the library's own piloted flights
(:func:`blind_flights`) or the independent simulator (:mod:`jaxheli.benchmark.truth`, :func:`trial_flights`)."""


def trial_flights(
    truth: str, kind: str, seed: int, where: Scenario, *, duration: float, dt: float, outputs: tuple[str, ...],
) -> tuple[Injection, FlightData, FlightData, tuple[str, ...], dict[str, Any]]:
    """A trial's flights by the ``truth`` simulator (:data:`TRUTHS_SIM`): ``(injection, train, validate, right,
    facts)``, ``injection`` the library kind the oracle fits at its true values, ``right`` the kinds a correct
    diagnosis names, ``facts`` what the record adds (the independent simulator's detectability and parts)."""
    if truth == "library":
        injection_seed, flight_seed = _library_seeds(kind, seed)
        inj = sample_injection(kind, injection_seed, outputs, duration, where.strength)
        train, validate = blind_flights(inj, flight_seed, where, duration=duration, dt=dt)
        score, train_score = (_library_detectability(inj, flight_seed, where, duration=duration,
                                                     dt=dt, outputs=outputs, train=role) for role in (False, True))
        return inj, train, validate, (kind,), {"detectability": score, "detectable": score > 1.0,
                                               "detectability_train": train_score,
                                               "resolvable": score > 1.0 and train_score > 1.0}
    if truth == "independent":
        ind = independent_trial(kind, seed, where.theta, style=where.style, noise=where.noise,
                                strength=where.strength, duration=duration, dt=dt, outputs=outputs)
        inj = Injection(ind.oracle, ind.eta, 0.0, 1.0, ind.primary, ind.value)
        return inj, ind.train, ind.validate, ind.candidates, {
            "oracle_kind": ind.oracle, "parts": list(ind.parts), "right": list(ind.candidates),
            "detectability": ind.score, "detectable": ind.detectable, "detectability_train": ind.train_score,
            "resolvable": ind.resolvable}
    raise ValueError(f"blind trial: unknown truth simulator {truth!r}; simulators are {tuple(TRUTHS_SIM)}")


def run_trial(
    kind: str, seed: int, *, base: str = "pem", truth: str = "library", duration: float = 30.0, dt: float = 0.05,
    segment: float = SEGMENT, max_steps: int = MAX_STEPS, pem_steps: int = 100, iterations: int = 1000,
    min_shrink: float = MIN_SHRINK, box: str = "hull", restart: str = RESTART,
) -> dict[str, Any]:
    """One blind trial: scenario and injection of ``seed``, flights, base model identified on the training
    flight by ``base`` (:func:`base_model`), joint diagnosis and oracle; the record (verdict, attribution, shrinks,
    ranking, the named effect's :func:`~jaxheli.gap.final_fit.final_fit`), flown by the ``truth`` simulator
    (:func:`trial_flights`; ``correct`` when the top candidate is one of the kinds that count as right). The
    magnitude is the one the diagnosis reports for the true kind (the oracle's): re-identified on both flights
    where it is the named effect, else its training fit (``estimate``, ``magnitude_error``); beside it the training
    fit's (``estimate_train``, ``magnitude_error_train``) and the oracle's (``oracle_estimate``,
    ``oracle_magnitude_error``). The base model is identified, and the diagnosis starts, in ``box``
    (:data:`BOXES`); the base model's structure is its first hypothesis (:func:`~jaxheli.gap.ranking.staged`).
    Every prediction restarts every ``segment`` s from the filter's state (``restart="filter"``) or from that
    state re-estimated by the segment's own readings
    (``"segment"``, :func:`~jaxheli.gap.segment_restart.restart_correction`;
    the defaults: the diagnosis's, :data:`~jaxheli.gap.predictor.RESTART`, :data:`~jaxheli.gap.predictor.SEGMENT`)."""
    if box not in BOXES:
        raise ValueError(f"blind trial: unknown box {box!r}; boxes are {tuple(BOXES)}")
    smooth = smooths(restart, "blind trial")
    where = scenario(seed)
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
    scored, credited = stages.ranked.scored, stages.ranked.credited
    best = next((e for e in ranking if e.significant), None)
    final = None
    if best is not None:
        with stage(f"final fit: {best.effect}'s size re-identified with the base model on both flights"):
            final = final_fit(train_pred, validate_pred, best, stages.box)
    top = best.effect if best else "none"
    oracle_z, oracle_stderr = np.asarray(scored.fit.z[-1]), np.asarray(scored.fit.stderr[-1])
    record = {"kind": kind, "seed": int(seed), "truth_sim": truth, **facts, "truth": where.truth,
              "style": where.style, "noise": where.noise, "strength": where.strength, "top": top,
              "correct": top in right,
              "in_tie": top in right or (best is not None and any(k in best.tied_with for k in right)),
              "true_value": inj.value, "primary": inj.primary,
              "oracle_shrink_pct": 100.0 * (1.0 - float(np.mean(scored.rows.gap[-1]) / np.mean(credited.gap[0]))),
              "oracle_evidence_z": (fx.evidence(inj.kind, outputs, oracle_z, oracle_stderr)
                                    if inj.kind != "none" else None),
              "box": box, "restart": restart, "segment_s": segment, "base": ident, "base_refit": _untheta(refit),
              "structure": None if structure is None else _untheta(structure),
              "structure_named": structure_leads(ranking, structure),
              "recheck": [_untheta(e) for e in stages.recheck],
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


def _untheta(result: Entry | Refit | Final | Structure) -> dict[str, Any]:
    """``result``'s JSON without its base parameters (a trial's record keeps the sizes, not 40 numbers each)."""
    return {k: v for k, v in result.to_json().items() if k != "theta"}


def _restrict(inj: Injection, outputs: tuple[str, ...]) -> Injection:
    """``inj`` on the channels ``outputs`` alone, as a user diagnoses a flight whose constant channels (a sensor
    quantised coarser than its channel moves) are left out: each effect parameter that still exists keeps its
    value."""
    eta = np.asarray(no_effect(outputs), np.float64).copy()
    kept = fx.params(inj.kind, outputs) if inj.kind != "none" else ()
    full = {p.name: p.slot for p in fx.params(inj.kind, DEFAULT_OUTPUTS)} if kept else {}
    for p in kept:
        eta[p.slot] = inj.eta[full[p.name]]
    if inj.primary in {p.name for p in kept}:
        return dataclasses.replace(inj, eta=eta)
    return dataclasses.replace(inj, eta=eta, primary=None, value=0.0)


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


def run_blind(
    trials: Sequence[Trial | tuple[str, int]],
    *,
    on_trial: Callable[[list[dict[str, Any]]], None] | None = None,
    workers: int = 1,
    **options: Any,
) -> list[dict[str, Any]]:
    """Diagnose each trial (a :class:`Trial` or ``(kind, seed)``) blind (:func:`run_trial` with ``options``);
    one record per trial, in the order of ``trials``. ``workers > 1`` runs trials in that many processes (each a
    trial at a time, in float64, each started on a core of its own when the machine has that many,
    :func:`_worker_cores`). A progress line reports each trial, with the time left (:func:`jaxheli.reporting`; in
    one process its stages too), and ``on_trial(records_so_far)`` runs after each, e.g. to save (records finished
    so far, in the order of ``trials``)."""
    done: dict[int, dict[str, Any]] = {}

    def finished(i: int, record: dict[str, Any]) -> None:
        done[i] = record
        if on_trial is not None:
            on_trial([done[j] for j in sorted(done)])

    trials = [Trial(*t) for t in trials]
    start = time.perf_counter()
    note(f"blind check: {len(trials)} trial(s) in {max(workers, 1)} process(es); each process's first trial "
         "compiles the solvers")
    if workers <= 1:
        for i, (kind, seed, base) in enumerate(trials):
            with stage(f"trial {i + 1} of {len(trials)}: {kind}, seed {seed}, {base} base model") as now:
                record = run_trial(kind, seed, base=base, **options)
                now.outcome = _outcome(record)
            finished(i, record)
            note(f"trials: {left(len(done), len(trials), time.perf_counter() - start)}")
    else:
        todo = iter(enumerate(trials))
        running: dict[Future, tuple[int, ProcessPoolExecutor]] = {}

        def feed(pool: ProcessPoolExecutor) -> None:
            trial = next(todo, None)
            if trial is not None:
                i, (kind, seed, base) = trial
                running[pool.submit(run_trial, kind, seed, base=base, **options)] = (i, pool)

        with contextlib.ExitStack() as stack:
            with stage(f"starting {workers} trial processes"):
                for core in _worker_cores(workers):
                    feed(stack.enter_context(_process_on(core)))
            with stage(f"{len(trials)} trials in {len(running)} processes"):
                while running:
                    for job in wait(running, return_when=FIRST_COMPLETED)[0]:
                        i, pool = running.pop(job)
                        finished(i, job.result())
                        kind, seed, base = trials[i]
                        note(f"trial {i + 1} of {len(trials)} ({kind}, seed {seed}, {base} base model): "
                             f"{_outcome(done[i])}; {left(len(done), len(trials), time.perf_counter() - start)}")
                        feed(pool)
    return [done[i] for i in range(len(trials))]


def _outcome(record: dict[str, Any]) -> str:
    """A finished trial in words: the effect it named and whether that is right."""
    return f"named {record['top']} ({'right' if record['correct'] else 'wrong'})"


def _worker_cores(workers: int) -> list[int | None]:
    """A core for each of ``workers`` trial processes, or ``None`` for each (not pinned) when the machine has fewer
    cores than that: on a 2-core CPU two unpinned JAX processes run about 3x slower than one (see
    :mod:`jaxheli._affinity`)."""
    usable = cores()
    return usable[:workers] if len(usable) >= workers else [None] * workers


def _process_on(core: int | None) -> ProcessPoolExecutor:
    """A one-process pool whose process is started (spawned) on ``core`` (:func:`~jaxheli._affinity.on_core`)
    before it imports JAX, in float64, watching this run (:func:`_worker`)."""
    context = multiprocessing.get_context("spawn")
    with on_core(core):
        pool = ProcessPoolExecutor(1, mp_context=context, initializer=_worker, initargs=(os.getpid(),))
        pool.submit(int).result()
    return pool


def _worker(parent: int) -> None:
    """A trial process's set-up: float64, and an exit once ``parent``, the run that spawned it, is gone
    (:func:`_exit_with`)."""
    jax.config.update("jax_enable_x64", True)
    threading.Thread(target=_exit_with, args=(parent,), daemon=True).start()


def _exit_with(parent: int, poll: float = 2.0) -> None:
    """End this process once its parent ``parent`` has ended (checked every ``poll`` s): a run stopped by a signal
    leaves no orphaned worker behind to finish its trial on cores nobody reads it from."""
    while os.getppid() == parent:
        time.sleep(poll)
    os._exit(1)


def identifiable(record: dict[str, Any]) -> bool:
    """A detectable trial (:func:`detectable`) whose *training* flight resolves the effect: the oracle's fitted
    size stands :data:`~jaxheli.gap.significance.MIN_Z` standard errors or more from no effect
    (:func:`~jaxheli.effects.registry.evidence`), the test every significant candidate must pass. The validation
    flight's 3-2-1-1 sticks (0.25) are larger than a regulating pilot's (about 0.08 at most): a saturation at 0.15-0.3
    stick then shrinks the held-out gap by 40-90 % once its true size is handed in, yet the training flight cannot
    tell it from none (e.g. 1 +- 26 1/stick^2 fitted for a true 65)."""
    z = record.get("oracle_evidence_z")
    return detectable(record) and z is not None and z >= MIN_Z


def explainable(record: dict[str, Any]) -> bool:
    """A detectable trial (:func:`detectable`) whose oracle, the right candidate fitted where the effect acts,
    shrinks the validation gap by :data:`~jaxheli.gap.significance.MIN_SHRINK` % or more: the trials any rule on
    the catalogue's forms could credit. A diagnostic of where misses come from (the form, or the rules), not a
    subset to score on: it hinges on the method's fit and floor."""
    return detectable(record) and record.get("oracle_shrink_pct", -np.inf) >= MIN_SHRINK


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
    the resolvable ones (:func:`resolvable`) and the identifiable ones (:func:`identifiable`), with the median relative
    magnitude error of each subset (the diagnosis's, its training fit's and the oracle's; a trial whose verdict does
    not name its effect counts its training fit's, so the detectable ones' are also given over the trials named right
    alone, ``magnitude_error_median_named``), and the median shrink
    vs oracle % (detectable), and the % of trials whose verdict names the base model's structure
    (:mod:`jaxheli.gap.structure`), and the explainable trials (:func:`explainable`) with their top-1 %; plus the
    false-positive % on effect-free flights."""
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
            row.update(_subset([r for r in seen if identifiable(r)], "identifiable"))
            reach = [r for r in seen if explainable(r)]
            row.update(explainable_trials=len(reach), top1_explainable_pct=_pct([r["correct"] for r in reach]))
            shrunk = [100.0 * r["shrink_pct"] / r["oracle_shrink_pct"] for r in seen if "shrink_pct" in r]
            row["shrink_vs_oracle_pct"] = float(np.median(shrunk)) if shrunk else None
        table[kind] = row
    controls = [r for r in records if r["kind"] == "none"]
    named = [r["top"] != "none" for r in controls]
    return {"kinds": table, "false_positive_pct": _pct(named), "false_positives": sum(named),
            "controls": len(controls), "false_positive_ci95_pct": wilson_interval(sum(named), len(controls))
            if controls else None}


def wilson_interval(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson score interval (%) of a rate seen ``k`` times in ``n`` trials (scipy's ``binomtest``): what ``n``
    controls can say about a false-positive rate (6 of 40: 7-29 %; 0 of 40: 0-9 %)."""
    ci = scipy.stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    return 100.0 * float(ci.low), 100.0 * float(ci.high)


def markdown(summary: dict[str, Any]) -> str:
    """The summary as a markdown table (with ``"bases"``, :func:`summarise_bases`, a pair of tables per other base
    method)."""
    lines = ["| kind | trials | top-1 % | in tie % | detectable (max_k rms(y_eff - y_clean) / sigma_k > 1) | "
             "top-1 % detectable | in tie % detectable | median magnitude error (detectable) | "
             "median magnitude error (detectable, named right) | "
             "resolvable (training flight too) | top-1 % resolvable | in tie % resolvable | "
             "median magnitude error (resolvable) | "
             f"identifiable (oracle z >= {MIN_Z:g}) | top-1 % identifiable | in tie % identifiable | "
             "median magnitude error (identifiable) | training fit's (identifiable) | oracle's (identifiable) | "
             f"median shrink vs oracle % | base structure named % | explainable (oracle shrink >= {MIN_SHRINK:g} %) | "
             "top-1 % explainable |",
             "|" + "---|" * 23]

    def cell(value: float | None, fmt: str) -> str:
        return "-" if value is None else format(value, fmt)

    def error(value: float | None) -> str:
        return "-" if value is None else f"{100 * value:.1f} %"

    for kind, row in summary["kinds"].items():
        subsets = "".join(f" | {row.get(f'{s}_trials', '-')} | {cell(row.get(f'top1_{s}_pct'), '.0f')}"
                          f" | {cell(row.get(f'in_tie_{s}_pct'), '.0f')}"
                          f" | {error(row.get(f'magnitude_error_median_{s}'))}"
                          + (f" | {error(row.get('magnitude_error_median_named'))}" if s == "detectable" else "")
                          for s in ("detectable", "resolvable", "identifiable"))
        lines.append(f"| {kind} | {row['trials']} | {cell(row['top1_pct'], '.0f')} | {cell(row['in_tie_pct'], '.0f')}"
                     f"{subsets} | {error(row.get('train_magnitude_error_median_identifiable'))}"
                     f" | {error(row.get('oracle_magnitude_error_median_identifiable'))}"
                     f" | {cell(row.get('shrink_vs_oracle_pct'), '.1f')} | {cell(row.get('structure_pct'), '.0f')}"
                     f" | {row.get('explainable_trials', '-')} | {cell(row.get('top1_explainable_pct'), '.0f')} |")
    ci = summary.get("false_positive_ci95_pct")
    lines.append(f"\nFalse positives on effect-free flights: {cell(summary['false_positive_pct'], '.0f')} %"
                 + (f" ({summary['false_positives']} of {summary['controls']}; 95 % Wilson interval "
                    f"{ci[0]:.0f}-{ci[1]:.0f} %)" if ci else ""))
    for method, both in summary.get("bases", {}).items():
        lines.append(f"\n### Base model by {method} against PEM, on the same trials (seeds {both['seeds']})\n")
        lines += [f"{m}:\n\n{markdown(both[m])}\n" for m in (method, "pem")]
    return "\n".join(lines)


def summarise_bases(records: list[dict[str, Any]]) -> dict[str, Any]:
    """:func:`summarise` of the PEM-base trials, with ``"bases"``: for every other base method (:data:`BASES`) that
    ran, its summary and the PEM-base summary of the same trials (kind and seed), side by side."""
    pem_rows = [r for r in records if r["base"]["method"] == "pem"]
    summary = summarise(pem_rows)
    summary["bases"] = {}
    for method in BASES[1:]:
        rows = [r for r in records if r["base"]["method"] == method]
        if rows:
            same = {(r["kind"], r["seed"]) for r in rows}
            seeds = sorted({r["seed"] for r in rows})
            summary["bases"][method] = {"seeds": f"{seeds[0]}-{seeds[-1]}", method: summarise(rows),
                                        "pem": summarise([r for r in pem_rows if (r["kind"], r["seed"]) in same])}
    return summary


def summarise_records(path: str | Path) -> dict[str, Any]:
    """:func:`summarise_bases` of the records in an earlier run's ``blind.json`` (``path``); a file without records
    is an error naming it."""
    try:
        records = json.loads(Path(path).read_text())["records"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{path}: not a blind run's records ({err!r})") from err
    return summarise_bases(records)


def run_benchmark(kinds: Sequence[str], seeds: int, out: str | Path, workers: int = 1, iwo_seeds: int = 0,
                  truth: str = "library", split: str = "design", control_seeds: int | None = None,
                  skip_seeds: int = 0, **options: Any) -> dict[str, Any]:
    """Run ``seeds`` blind trials per effect kind and ``control_seeds`` (default ``2 seeds``) of the control
    ``none``, on the first seeds of ``split`` after ``skip_seeds`` (the protocol of :mod:`jaxheli.gap.thresholds`:
    every kind meets the same scenarios), with a PEM base model, and the first ``iwo_seeds`` of them again with an
    IWO + polish base
    (:func:`base_model`), in ``workers`` processes; write ``OUT/blind.json`` (records, :func:`summarise_bases`, the
    settings with the thresholds in force) and ``OUT/blind.md`` after every trial. ``truth`` picks the truth
    simulator (:data:`TRUTHS_SIM`), whose kinds ``kinds`` are."""
    if truth not in TRUTHS_SIM:
        raise ValueError(f"blind benchmark: unknown truth simulator {truth!r}; simulators are {tuple(TRUTHS_SIM)}")
    bad = [k for k in kinds if k not in TRUTHS_SIM[truth]]
    if bad:
        raise ValueError(f"blind benchmark: unknown kinds {bad} for the {truth} truth; kinds are {TRUTHS_SIM[truth]}")
    t0 = time.perf_counter()
    control_seeds = 2 * seeds if control_seeds is None else control_seeds
    drawn = {k: THRESHOLDS.protocol.seeds(split, control_seeds if k == "none" else seeds, skip_seeds) for k in kinds}
    settings = {"kinds": list(kinds), "split": split, "seeds": seeds, "control_seeds": control_seeds,
                "skip_seeds": skip_seeds,
                "seed_range": [min(min(s) for s in drawn.values() if s), max(max(s) for s in drawn.values() if s)],
                "iwo_seeds": iwo_seeds, "workers": workers, "truth": truth, **options,
                "thresholds": {**{f.name: getattr(THRESHOLDS, f.name) for f in dataclasses.fields(THRESHOLDS)
                                  if f.name not in ("protocol", "source")}, "file": THRESHOLDS.source},
                "base_model": "PEM (every trial) or IWO + polish (the first iwo_seeds) on the contaminated "
                              "training flight in the box blind.BOXES[box], never the truth",
                "diagnosis": "joint re-identification (default of jaxheli diagnose)"}
    order = sorted({s for ss in drawn.values() for s in ss})
    trials = ([Trial(k, s) for s in order for k in kinds if s in drawn[k]]
              + [Trial(k, s, "iwo+polish") for k in kinds for s in drawn[k][:iwo_seeds]])
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    def save(records: list[dict[str, Any]]) -> dict[str, Any]:
        summary = summarise_bases(records)
        summary["runtime_s"] = time.perf_counter() - t0
        summary["settings"] = settings
        summary["complete"] = len(records) == len(trials)
        (out / "blind.json").write_text(json.dumps({"summary": summary, "records": records}, indent=2))
        (out / "blind.md").write_text(markdown(summary) + f"\n\nRuntime {summary['runtime_s']:.0f} s.\n")
        return summary

    return save(run_blind(trials, on_trial=save, workers=workers, truth=truth, **options))
