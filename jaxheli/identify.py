"""One entry point for every identification: :func:`identify` runs a chain of stages (:mod:`jaxheli.stages`: IWO or
GA, PEM, the frequency fit, the polish, the structure determination), a named method or the caller's, then computes
Cramer-Rao standard errors and 95 % intervals over trials, and scores the result on the training flight and, if
given, a validation flight (and the truth beside it when it is known). The result object holds everything
:func:`jaxheli.results.save_result` writes (JSON, NPZ, PNG).
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Sequence
from typing import Any

import jax
import numpy as np
import scipy.stats

from ._progress import stage
from ._types import Float
from .data.flight import FlightData, constant_outputs, default_outputs
from .data.preprocess import bandwidth_step, input_cutoff, resample
from .evaluate import evaluate
from .model import G_SI, LOWER, PARAM_NAMES, UPPER
from .optim.frequency_fit import FrequencyFitResult, cifer_report
from .optim.uncertainty import Uncertainty, cramer_rao_coverage, standard_errors
from .problem import Problem, Records, as_problem, make_problem, parts
from .stages import FrequencyFit, PEM, Polish, Record, Search, Stage, Task, method_chain


@dataclasses.dataclass
class IdentificationResult:
    """What an identification run produced.

    Attributes:
        method, seed: how it was run; ``settings`` holds every other choice (simulation included).
        params: ``[40]`` the identified parameters (best trial, polished when the method says so).
        trial_params, trial_costs: ``[K, 40]`` and ``[K]`` each trial's final parameters and training cost.
        history: ``[K, iterations]`` best cost per generation (population methods; empty for PEM).
        intervals95: ``{name: (low, high)}`` t-interval of the trial mean (``None`` for one trial).
        stderr: ``{name: value}`` Cramer-Rao standard errors at ``params`` (inf: not identifiable, or every free
            parameter when the model diverges in the simulation they are computed on).
        train, validate: metric blocks of :func:`jaxheli.evaluate` (``validate`` ``None`` without a flight);
            ``validate["zero_initial_state"]`` repeats the scores from rest, the paper's convention.
        polish: the best unpolished parameters, the search cost and the polish's own objective before and after
            the gradient polish, and that objective at the start and end of each polish round
            (``objective_rounds``) (``None`` unless polished).
        seconds: wall time of the fit.
        truth: when the true parameters are known (synthetic flights): their parameters, their scores as
            ``train`` / ``validate`` and ``cramer_rao`` (:func:`~jaxheli.optim.uncertainty.cramer_rao_coverage`);
            else ``None``.
        frequency: frequency methods: Tischler's ``J`` per (input, output) pair at ``params``, their bins, the
            average ``J`` and ``acceptable`` (``<= 100``), with the best trial's frequency fit under ``"fit"``
            (its own ``J``s, starts, band; :class:`~jaxheli.optim.frequency_fit.FrequencyFitResult`); else ``None``.
        fixed: after a model-structure determination (:class:`~jaxheli.stages.Structure`), the parameters it fixed,
            ``{name: {"value", "reason", "round", "relative_se", "partner", "rho", "source"}}``
            (:class:`~jaxheli.optim.structure.FixedParameter`; empty when it fixed none); else ``None``.
        structure: its rounds, the output-error sums of squares before and after, and its settings
            (:meth:`~jaxheli.optim.structure.StructureResult.to_json` without ``fixed``); else ``None``.
        convergence: methods fitted by PEM: each trial's Levenberg-Marquardt ``steps``, ``result`` and whether it
            ``converged``, and whether the best trial did (``result.json`` holds it only then); else ``None``.
    """

    method: str
    seed: int
    settings: dict[str, Any]
    params: np.ndarray
    trial_params: np.ndarray
    trial_costs: np.ndarray
    history: np.ndarray
    intervals95: dict[str, tuple[float, float]] | None
    stderr: dict[str, float]
    train: dict[str, Any]
    validate: dict[str, Any] | None
    polish: dict[str, Any] | None
    seconds: float
    truth: dict[str, Any] | None = None
    frequency: dict[str, Any] | None = None
    fixed: dict[str, dict[str, Any]] | None = None
    structure: dict[str, Any] | None = None
    convergence: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready content (``result.json``); parameters and intervals named as in :data:`PARAM_NAMES`."""
        return {
            "method": self.method,
            "seed": self.seed,
            "settings": self.settings,
            "parameters": dict(zip(PARAM_NAMES, map(float, self.params))),
            "intervals95": None if self.intervals95 is None else {k: list(v) for k, v in self.intervals95.items()},
            "stderr": {k: (v if np.isfinite(v) else "inf") for k, v in self.stderr.items()},
            "trial_costs": [float(c) for c in self.trial_costs],
            "train": self.train,
            "validate": self.validate,
            "polish": self.polish,
            "seconds": self.seconds,
            "truth": self.truth,
            "frequency": self.frequency,
            "fixed": self.fixed,
            "structure": self.structure,
        } | ({} if self.convergence is None else {"convergence": self.convergence})


def intervals95(trial_params: Float[np.ndarray, "K 40"]) -> dict[str, tuple[float, float]] | None:
    """95 % t-interval of the mean of each parameter over K trials (``None`` when K < 2)."""
    k = trial_params.shape[0]
    if k < 2:
        return None
    mean = trial_params.mean(axis=0)
    half = scipy.stats.t.ppf(0.975, k - 1) * trial_params.std(axis=0, ddof=1) / np.sqrt(k)
    return {n: (float(m - h), float(m + h)) for n, m, h in zip(PARAM_NAMES, mean, half)}


PROBLEM_DEFAULTS: dict[str, Any] = {"outputs": None, "segment": None, "hold": "auto", "g": G_SI, "lower": LOWER,
                                    "upper": UPPER, "cost": "pearson", "search_precision": "float32"}
"""The settings of the problem :func:`identify` builds from flights, where not given: the flight's measured channels
without a, b; one run from rest (``segment``, s); the input hold ``"auto"``, first-order where every training
flight's sticks were low-passed (:func:`~jaxheli.data.preprocess.lowpass`: smooth between samples, MATLAB ``lsim``'s
choice for smooth inputs), zero-order otherwise (``"zoh"`` / ``"foh"`` to choose); gravity, m/s^2; the authors'
box; the paper's Pearson cost (Eq. 7) for the search (``"output-error"``: :func:`jaxheli.cost.output_error_cost`),
scored in float32 (several times faster, its costs within 1e-3 of float64's, ``tests/test_blocked.py``; every other
stage and metric run in the session's precision)."""

_ABSENT: dict[str, Any] = {**Search().settings(), **PEM().settings(), **FrequencyFit().settings(),
                           **Polish().settings(), "polish_objective": None, "structure": False}
"""What ``settings`` records for the options of a stage the chain lacks: the stage's defaults, and no polish."""


def identify(
    data: FlightData | Sequence[FlightData] | Problem | Records,
    method: str | Sequence[Stage] = "iwo+freq+polish",
    *,
    validate: FlightData | None = None,
    trials: int = 1,
    seed: int = 0,
    truth: Float[np.ndarray, "40"] | None = None,
    fit_dt: float | str | None = "auto",
    **options: Any,
) -> IdentificationResult:
    """Identify the 40 hover-model parameters from a training record by a chain of stages (:mod:`jaxheli.stages`).

    Args:
        data: a flight, several flights (fitted at once: each its own initial state, costs add), or a
            :class:`~jaxheli.problem.Problem` / :class:`~jaxheli.problem.Records`, whose settings replace the
            problem's options (one given otherwise is a one-line ``ValueError``).
        method: a named method (:data:`~jaxheli.stages.CHAINS`: ``"iwo"``, ``"ga"``, ``"pem"``, ``"iwo+polish"``,
            ``"freq"``, ``"freq+polish"``, ``"iwo+freq+polish"``), or the stages to run in order.
        validate: a held-out flight, scored with an estimated initial state and from rest.
        trials: ``K`` independent trials (their spread gives the 95 % intervals; the paper: 10).
        seed: PRNG seed; the run is a deterministic function of it.
        truth: the true parameters, scored beside the result with the share of identifiable parameters within 3
            Cramer-Rao standard errors of them (default: a synthetic flight's ``metadata["truth"]`` when it carries
            no unmodelled effect).
        fit_dt: the step (s) the stages fit each flight at, resampled (:func:`~jaxheli.data.preprocess.resample`,
            which does not filter: the flight must be low-passed below its Nyquist rate); ``"auto"``: a low-passed
            flight's :func:`~jaxheli.data.preprocess.bandwidth_step`, the others (and a ``Problem``) at their own
            step (the default); ``None`` or ``"full"``: every flight at its own step. The standard errors and every
            score use the flights at their own step (a structure determination's standard errors excepted: they
            are its fit's).
        options: the problem's settings (:data:`PROBLEM_DEFAULTS`) and, for a named method, its stages' options
            (:data:`~jaxheli.stages.KEYWORDS`: ``iterations``, ``polish_steps``, ``structure``, ...); one that no
            stage of the chain uses is a one-line ``ValueError``, and ``None`` leaves an option out.
    """
    options = {k: v for k, v in options.items() if v is not None}
    name, chain = method_chain(method, options)
    if trials < 1:
        raise ValueError(f"identify: trials must be >= 1, got {trials}")
    given = {k: v for k, v in options.items() if k in PROBLEM_DEFAULTS}
    fit_data, fit_steps = _at_fit_step(data, fit_dt)
    if isinstance(data, (Problem, Records)):
        _refuse_conflicts(data.settings, given)
        problem = fit_problem = data
    else:
        chosen = {**PROBLEM_DEFAULTS, **given}
        chosen["hold"] = _hold(data, chosen["hold"])
        precision = chosen.pop("search_precision")
        problem = as_problem(data, None, precision=precision, **chosen)
        fit_problem = problem if fit_data is data else as_problem(fit_data, None, precision=precision, **chosen)
    task = Task(fit_problem.variant(x0="zero"), fit_data, trials, seed)
    for step in chain:
        step.check(task)
    t0 = time.perf_counter()
    starts, record = None, Record()
    for step in chain:
        starts, found = step(task, starts)
        record = record.merge(found)
    params = starts.params[starts.best] if record.structure is None else record.structure.theta
    convergence = None if record.convergence is None else _convergence(record.convergence, starts.best)
    full = problem.variant(x0="zero")
    fitted, scored = chain[-1].errors_problem(full, params), chain[-1].fitted(full)
    seconds = time.perf_counter() - t0
    if record.structure is None:
        with stage("standard errors (Cramer-Rao) at the best parameters") as now:
            unc = standard_errors(fitted, params, nonfinite="unresolved")
            now.outcome = f"{int(np.sum(np.isfinite(unc.stderr) & (unc.stderr > 0)))} parameters resolved"
    else:
        unc = record.structure.uncertainty
    settings = problem.settings
    own = {**_ABSENT, **{k: v for step in chain for k, v in step.settings().items()}}
    kept = {
        "method": name, "iterations": own["iterations"], "trials": trials, "outputs": list(problem.outputs),
        "segment": settings.segment, "hold": settings.hold, "g": settings.g, "pem_segment": own["pem_segment"],
        "lower": list(settings.lower), "upper": list(settings.upper), "cost": settings.cost,
        "polish_objective": own["polish_objective"], "polish_steps": own["polish_steps"],
        "polish_rounds": own["polish_rounds"], "cv_windows": own["cv_windows"],
        "train_source": str(problem.source), "fit_dt": fit_steps,
        "validate_source": None if validate is None else validate.source,
        "x64": bool(jax.config.jax_enable_x64), "search_precision": settings.precision,
        "engine_options": own["engine_options"], "freq_options": own["freq_options"],
        "frequency_skipped": record.skipped,
        "structure": own["structure"], "prior": own["prior"], "prior_sd": own["prior_sd"],
        "evaluations": record.evaluations,
        "standard_errors": [part.sim.describe() for part in parts(fitted)],
    }
    truth = _known_truth(data) if truth is None else np.asarray(truth, dtype=np.float64)
    found = record.structure
    with stage("scores on the training flight" + ("" if validate is None else " and the validation flight")
               + ("" if truth is None else ", and the truth's beside them")):
        return IdentificationResult(
            method=name,
            seed=seed,
            settings=kept,
            params=params,
            trial_params=starts.params,
            trial_costs=starts.costs,
            history=np.zeros((trials, 0)) if record.history is None else record.history,
            intervals95=intervals95(starts.params),
            stderr=dict(zip(PARAM_NAMES, map(float, unc.stderr))),
            train=scores(params, scored),
            validate=None if validate is None else validation_block(params, validate, problem),
            polish=record.polish,
            seconds=seconds,
            truth=None if truth is None else _truth_block(truth, unc, scored, validate, problem),
            frequency=None if record.fits is None else _frequency_block(record.fits, params),
            fixed=None if found is None else found.fixed_dict(),
            structure=None if found is None else {k: v for k, v in found.to_json().items() if k != "fixed"},
            convergence=convergence,
        )


def _at_fit_step(
    data: FlightData | Sequence[FlightData] | Problem | Records, fit_dt: float | str | None
) -> tuple[FlightData | Sequence[FlightData] | Problem | Records, list[float] | None]:
    """The training record the stages fit (``data`` itself unless a flight's fitting step differs from its own) and
    each flight's fitting step, s (``None``: every flight at its own); see :func:`identify`'s ``fit_dt``."""
    if fit_dt is None or fit_dt == "full" or (fit_dt == "auto" and isinstance(data, (Problem, Records))):
        return data, None
    if isinstance(data, (Problem, Records)):
        raise ValueError(f"identify: fit_dt={fit_dt!r} needs flights, got a {type(data).__name__} (build it from the "
                         "flights resampled to the step: jaxheli.resample)")
    if isinstance(fit_dt, str) and fit_dt != "auto":
        raise ValueError(f"identify: fit_dt must be 'auto', 'full', None or a step in seconds, got {fit_dt!r}")
    flights = [data] if isinstance(data, FlightData) else list(data)
    steps = [bandwidth_step(f) if fit_dt == "auto" else float(fit_dt) for f in flights]
    for f, step in zip(flights, steps):
        if step is not None and not step >= f.dt * (1.0 - 1e-9):
            raise ValueError(f"identify: fit_dt {step:g} s is finer than {f.source}'s own step {f.dt:g} s")
    steps = [f.dt if step is None else step for f, step in zip(flights, steps)]
    if all(abs(step - f.dt) <= 1e-9 * f.dt for f, step in zip(flights, steps)):
        return data, None
    coarse = [resample(f, step) for f, step in zip(flights, steps)]
    return (coarse[0] if isinstance(data, FlightData) else coarse), steps


def _convergence(trials: list[dict[str, Any]], best: int) -> dict[str, Any]:
    """The local fit's convergence per trial and of the best; a warning when the best stopped at its step limit
    (its answer may lie short of the optimum of its own objective)."""
    chosen = trials[best]
    if not chosen["converged"]:
        warnings.warn(f"identify: the best trial's least-squares fit stopped before converging ({chosen['result']} "
                      f"after {chosen['steps']} steps): its parameters may lie short of the optimum; give it more "
                      "steps", stacklevel=3)
    return {"trials": trials, "converged": bool(chosen["converged"])}


def scores(params: Float[np.ndarray, "40"], problem: Problem | Records) -> dict[str, Any]:
    """Metrics of ``params`` on ``problem``'s record (:func:`jaxheli.evaluate`): initial state estimated, and
    from rest under ``"zero_initial_state"`` (the paper's convention)."""
    block = evaluate(params, problem, x0="estimate")
    block["zero_initial_state"] = evaluate(params, problem, x0="zero")
    return block




def _frequency_block(fits: list[FrequencyFitResult], params: Float[np.ndarray, "40"]) -> dict[str, Any]:
    """Tischler's ``J`` per pair at ``params`` on the frequency fit's bins, and the best trial's fit."""
    best = min(fits, key=lambda f: f.j_average)
    return {**cifer_report(best.targets, params), "fit": best.to_dict()}


_SETTING_OF = {"search_precision": "precision"}
"""``identify``'s option names that differ from the :class:`~jaxheli.problem.Settings` field they set."""


def _hold(data: FlightData | Sequence[FlightData], hold: str) -> str:
    """The input hold of :data:`PROBLEM_DEFAULTS`'s ``"auto"`` for these flights (see there), or ``hold`` as given."""
    if hold != "auto":
        return hold
    flights = [data] if isinstance(data, FlightData) else list(data)
    return "foh" if all(input_cutoff(f) is not None for f in flights) else "zoh"


def _refuse_conflicts(settings: Any, given: dict[str, Any]) -> None:
    """Raise a one-line ``ValueError`` naming every flight setting given to :func:`identify` beside a
    ``Problem`` that differs both from the argument's default and from the problem's own setting."""
    clash = []
    for name, value in given.items():
        default, own = PROBLEM_DEFAULTS[name], getattr(settings, _SETTING_OF.get(name, name))
        if _same(value, default) or _same(value, own):
            continue
        clash.append(f"{name}={value!r} (the problem has {own!r})")
    if clash:
        raise ValueError("identify: data is a Problem, whose settings replace " + "; ".join(clash)
                         + ": build the problem with them (jaxheli.make_problem) or pass the flight")


def _same(a: Any, b: Any) -> bool:
    if a is None or b is None or isinstance(a, str) or isinstance(b, str):
        return a == b
    if isinstance(a, (list, tuple)) and all(isinstance(x, str) for x in a):
        return isinstance(b, (list, tuple)) and tuple(a) == tuple(b)
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and bool(np.array_equal(a, b))


def _known_truth(data: FlightData | Sequence[FlightData] | Problem | Records) -> np.ndarray | None:
    """Synthetic flights' true parameters, when they all have the same and carry no unmodelled effect."""
    flights = [data] if isinstance(data, FlightData) else list(data) if isinstance(data, (list, tuple)) else []
    truths = {None if f.metadata.get("effect") is not None else _tuple(f.metadata.get("truth")) for f in flights}
    truth = truths.pop() if len(truths) == 1 else None
    return None if truth is None else np.asarray(truth, dtype=np.float64)


def _tuple(values: list[float] | None) -> tuple[float, ...] | None:
    return None if values is None else tuple(values)


def _truth_block(
    truth: np.ndarray, unc: Uncertainty, scored: Problem | Records, validate: FlightData | None,
    problem: Problem | Records,
) -> dict[str, Any]:
    """The truth's parameters and scores (as the result's), and its distance in standard errors."""
    return {
        "parameters": dict(zip(PARAM_NAMES, map(float, truth))),
        "train": scores(truth, scored),
        "validate": None if validate is None else validation_block(truth, validate, problem),
        "cramer_rao": cramer_rao_coverage(unc, truth),
    }


def validation_block(
    params: Float[np.ndarray, "40"], flight: FlightData, problem: Problem | Records | tuple[str, ...], **options
) -> dict[str, Any]:
    """Scores on a held-out flight: initial state estimated (default) and from rest (the paper).

    ``problem`` is the training problem (its scored channels, hold, g and segment apply) or, with
    ``options`` (:class:`~jaxheli.problem.Settings` fields), the scored channels."""
    if isinstance(problem, (Problem, Records)):
        outputs, options = problem.outputs, {"hold": problem.settings.hold, "g": problem.settings.g,
                                             "segment": problem.settings.segment}
    else:
        outputs = tuple(problem)
    flat = constant_outputs(flight)
    chans = tuple(c for c in outputs if c in flight.output_names and c not in flat) or default_outputs(flight)
    return scores(params, make_problem(flight, outputs=chans, **options))
