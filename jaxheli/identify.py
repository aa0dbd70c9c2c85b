"""One entry point for every identification method: IWO, GA, PEM, frequency domain (CIFER), and IWO or the
frequency fit followed by a gradient polish.

``identify(flight, method=...)`` runs the chosen engine (K trials vmapped in one scan for the population
methods) on its search cost (the paper's Pearson cost by default; Tischler's frequency-response cost J for the
frequency fit), polishes when asked (by default on the output error, so gains and offsets are identified),
computes Cramer-Rao standard errors and 95 % intervals over trials, and scores the result on the training flight
and, if given, a validation flight (and the truth beside it when it is known). The result object holds
everything :func:`jaxheli.results.save_result` writes (JSON, NPZ, PNG).
"""

from __future__ import annotations

import dataclasses
import inspect
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import jax
import numpy as np
import scipy.stats

from ._progress import note, stage
from ._types import Float
from .cost import SearchCost
from .data.flight import FlightData, constant_outputs, default_outputs
from .evaluate import evaluate, resolve_params, search_cost_of
from .model import G_SI, LOWER, PARAM_NAMES, UPPER
from .optim.cross_validate import CrossValidation, check_windows, cross_validate
from .optim.frequency_fit import FrequencyFitResult, IncoherentFlight, cifer_report, frequency_fit
from .optim.ga import GA
from .optim.iwo import IWO
from .optim.pem import PEMResult, pem
from .optim.output_error import output_error_problem
from .optim.polish import PolishObjective, polish
from .optim.prior import Prior
from .optim.structure import LocalFit, determine_structure
from .optim.run import minimize, minimize_trials
from .optim.uncertainty import Uncertainty, cramer_rao_coverage, standard_errors
from .problem import Problem, Records, as_problem, make_problem, parts

Method = Literal["iwo", "ga", "pem", "iwo+polish", "freq", "freq+polish", "iwo+freq+polish"]
METHODS: tuple[str, ...] = ("iwo", "ga", "pem", "iwo+polish", "freq", "freq+polish", "iwo+freq+polish")
PRIOR_SD = 50.0
"""Default standard deviation of a prior model, percent of each value (floored, :mod:`jaxheli.optim.prior`): a weak
prior, which a record that determines a parameter overrules; a tighter one is a choice to state (``prior_sd``)."""


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
        fixed: with ``structure=True``, the parameters the model-structure determination fixed,
            ``{name: {"value", "reason", "round", "relative_se", "partner", "rho", "source"}}``
            (:class:`~jaxheli.optim.structure.FixedParameter`; empty when it fixed none); else ``None``.
        structure: its rounds, the output-error sums of squares before and after, and its settings
            (:meth:`~jaxheli.optim.structure.StructureResult.to_json` without ``fixed``); else ``None``.
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
        }


def intervals95(trial_params: Float[np.ndarray, "K 40"]) -> dict[str, tuple[float, float]] | None:
    """95 % t-interval of the mean of each parameter over K trials (``None`` when K < 2)."""
    k = trial_params.shape[0]
    if k < 2:
        return None
    mean = trial_params.mean(axis=0)
    half = scipy.stats.t.ppf(0.975, k - 1) * trial_params.std(axis=0, ddof=1) / np.sqrt(k)
    return {n: (float(m - h), float(m + h)) for n, m, h in zip(PARAM_NAMES, mean, half)}


def identify(
    data: FlightData | Sequence[FlightData] | Problem | Records,
    *,
    method: Method = "iwo+freq+polish",
    validate: FlightData | None = None,
    iterations: int = 1000,
    trials: int = 1,
    seed: int = 0,
    outputs: tuple[str, ...] | list[str] | None = None,
    segment: float | None = None,
    hold: Literal["zoh", "foh"] = "zoh",
    g: float = G_SI,
    lower: Float[np.ndarray, "40"] = LOWER,
    upper: Float[np.ndarray, "40"] = UPPER,
    start: Float[np.ndarray, "40"] | None = None,
    cost: SearchCost = "pearson",
    polish_objective: PolishObjective = "output-error",
    polish_steps: int = 100,
    polish_rounds: int = 4,
    cv_windows: int = 0,
    pem_segment: float = 5.0,
    search_precision: Literal["float32", "float64"] = "float32",
    engine_options: dict[str, Any] | None = None,
    freq_options: dict[str, Any] | None = None,
    truth: Float[np.ndarray, "40"] | None = None,
    structure: bool = False,
    prior: str | Float[np.ndarray, "40"] | dict | None = None,
    prior_sd: float = PRIOR_SD,
    chunk: int = 50,
    checkpoint: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> IdentificationResult:
    """Identify the 40 hover-model parameters from a training record.

    Args:
        data: training record: a flight (its problem is built from ``outputs``, ``segment``, ``hold``, ``g``,
            ``lower``, ``upper``, ``cost``, ``search_precision``), several flights (fitted at once: each its own
            initial state, costs add; :class:`~jaxheli.problem.Records`), or a :class:`~jaxheli.problem.Problem`
            or :class:`~jaxheli.problem.Records` whose settings replace those arguments (one of them given a value
            other than its default and the problem's own raises a one-line ``ValueError``).
        method: ``"iwo"``, ``"ga"``, ``"pem"``, ``"iwo+polish"`` (IWO, then optimistix on ``polish_objective``),
            ``"freq"`` (frequency responses fitted on Tischler's cost J, :func:`~jaxheli.optim.frequency_fit.
            frequency_fit`), ``"freq+polish"`` (that, then the polish) or ``"iwo+freq+polish"`` (the default: IWO
            on the search cost, its best starting the frequency fit beside the fit's screened draws; the polish's
            first round tries the lowest J and IWO's best and goes on from the better. IWO alone can settle where
            the rotor and stabilizer-bar time constants trade places, the frequency fit alone from the box's draws
            in a minimum of J with a coupling of the wrong sign).
        validate: optional held-out record, scored with an estimated initial state and from rest.
        iterations: generations of IWO / GA (the paper: 1000).
        trials: independent trials (vmapped); their spread gives the 95 % intervals (the paper: 10).
        seed: PRNG seed; the run is a deterministic function of it.
        outputs: channels of the cost (default: the flight's measured channels without a, b).
        segment: restart interval of the search's simulation, s (``None``: the paper's single run from rest).
        hold, g: simulation settings (:func:`jaxheli.make_simulator`).
        lower, upper: search box of every engine (population, PEM, polish, standard errors; default: the
            authors' bounds).
        start: PEM's start (default: the middle of the bounds; random in the box for trials > 1); the frequency
            fit's first start for ``"freq"`` / ``"freq+polish"`` (default: its best screened draws only; for
            ``"iwo+freq+polish"`` each trial's IWO best).
        cost: what IWO / GA minimise: ``"pearson"`` (the paper's Eq. 7) or ``"output-error"``
            (:func:`jaxheli.cost.output_error_cost`).
        polish_objective: ``"output-error"`` (default: normalised output errors, every run from its least-squares
            state, runs shortened where the model is unstable, :mod:`jaxheli.optim.output_error`), ``"pearson"`` (the
            paper's cost: with ``cost="pearson"`` the paper's pure pipeline) or ``"pem"``
            (:func:`jaxheli.optim.polish.polish`).
        polish_steps, polish_rounds: Levenberg-Marquardt steps per round, and the most rounds (output error only).
        cv_windows: with the output-error polish on one flight, choose the polish's last run length and its
            stopping round by leave-one-window-out cross-validation over that many windows of the flight
            (:func:`~jaxheli.optim.cross_validate.cross_validate`; the folds start from the polish's own starts);
            0 (default) keeps the polish's full schedule.
        pem_segment: predictor restart interval of PEM, s (keeps unstable candidates usable).
        search_precision: arithmetic of the IWO / GA population scoring (float32, the default, is several
            times faster and its costs agree with float64 to 1e-3, see ``tests/test_blocked.py``); the polish,
            PEM and every reported metric run in the session's precision (float64 unless disabled).
        engine_options: further hyperparameters of :class:`~jaxheli.optim.IWO` / :class:`~jaxheli.optim.GA`
            (e.g. ``{"modulation": 3.0}``; default: the paper's settings).
        freq_options: keywords of the frequency fit (``starts``, ``screen``, ``band``, ``min_coherence``,
            ``max_steps``, ...); trial ``k`` of the frequency fit draws its starts from ``seed + k``.
        truth: the true parameters when known (default: a synthetic flight's ``metadata["truth"]`` when it
            carries no unmodelled effect); scored beside the result, with the share of identifiable parameters
            within 3 Cramer-Rao standard errors of it.
        structure: after the fit, determine the model structure (:func:`~jaxheli.optim.structure.
            determine_structure`): parameters the record cannot determine (unresolved, relative Cramer-Rao bound
            above 20 %, or the worse of a pair correlated above 0.95) are fixed (to the prior's value, else 0 or the
            nearest bound) and the method's local fit (PEM; the polish's output error or PEM) repeated with them
            pinned, until nothing more is fixed; ``params``, ``stderr`` and the scores are the re-fit's. Needs a
            least-squares fit: ``method="pem"`` or a ``+polish`` method whose ``polish_objective`` is not
            ``"pearson"``.
        prior, prior_sd: a prior model (anything :func:`jaxheli.evaluate.resolve_params` reads: a result.json, a
            name such as ``"table2"``, 40 values) and its standard deviation in percent of each value (floored,
            :mod:`jaxheli.optim.prior`): its residuals join those of every local fit (PEM, the polish; not the
            population search or the frequency fit), and fixed parameters take its values.
        chunk, checkpoint, resume, progress: run control of :func:`jaxheli.optim.run.minimize`.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if trials < 1 or iterations < 1:
        raise ValueError(f"trials and iterations must be >= 1, got {trials}, {iterations}")
    if cv_windows:
        if not (method.endswith("+polish") and polish_objective == "output-error" and isinstance(data, FlightData)):
            raise ValueError("cv_windows needs a +polish method on the output-error objective and one training "
                             f"flight (not several, not a Problem); got {method!r}, {polish_objective!r}, "
                             f"{type(data).__name__}")
        check_windows(data, cv_windows)
    local_fit = _local_fit(method, polish_objective) if structure else None
    belief = None if prior is None else Prior.from_percent(resolve_params(prior), prior_sd)
    given = {"outputs": outputs, "segment": segment, "hold": hold, "g": g, "lower": lower, "upper": upper,
             "cost": cost, "search_precision": search_precision}
    if isinstance(data, (Problem, Records)):
        _refuse_conflicts(data.settings, given)
        problem = data
    else:
        problem = as_problem(data, None, precision=given.pop("search_precision"), **given)
    settings = problem.settings
    t0 = time.perf_counter()
    key = jax.random.PRNGKey(seed)
    history, evaluations = np.zeros((trials, 0)), None
    polish_info = fits = skipped = None
    if method == "pem":
        fitted = problem.variant(segment=pem_segment, x0="measured")
        trial_params, trial_costs = _pem_trials(fitted, key, trials, start, belief)
        scored = fitted
    else:
        search = problem.variant(x0="zero")
        if not method.startswith("freq"):
            run_options = {"chunk": chunk, "progress": progress, "checkpoint": checkpoint, "resume": resume}
            with stage(f"{'GA' if method == 'ga' else 'IWO'}: {trials} trial(s) of {iterations} generations on the "
                       f"{settings.cost} cost (the first chunk compiles)") as now:
                trial_params, trial_costs, history, evaluations = _population_trials(
                    search, GA if method == "ga" else IWO, iterations, engine_options, key, trials, run_options)
                now.outcome = f"best cost {float(np.min(trial_costs)):.6g}"
        searched = trial_params if method == "iwo+freq+polish" else None
        if "freq" in method:
            starts = [start] * trials if searched is None else list(searched)
            try:
                fits = [_frequency_trial(search, starts[k], seed + k, k, trials, freq_options) for k in range(trials)]
            except IncoherentFlight as error:
                if searched is None:
                    raise
                skipped, searched = f"frequency fit skipped, IWO's best polished alone: {error}", None
                warnings.warn(skipped, stacklevel=2)
            else:
                trial_params, trial_costs = np.stack([f.theta for f in fits]), np.array([f.j_average for f in fits])
        fitted = scored = search
        if method.endswith("+polish"):
            chosen = None if not cv_windows else _cross_validation(
                data, search, trial_params, trial_costs, searched, cv_windows, polish_steps, polish_rounds, belief)
            trial_params, trial_costs, polish_info = _polish_trials(
                search, trial_params, trial_costs, polish_objective, polish_steps, polish_rounds, searched, belief,
                chosen)
        if (method.endswith("+polish") and polish_objective == "output-error") or method == "freq":
            # standard errors with restarts where unstable: a frequency fit may diverge over one run from rest
            fitted = output_error_problem(search, trial_params[int(np.argmin(trial_costs))])
    best = int(np.argmin(trial_costs))
    params = trial_params[best]
    found = None
    if local_fit is not None:
        with stage("model-structure determination: fix poorly determined parameters and re-fit") as now:
            found = determine_structure(fitted if method == "pem" else search, params, local_fit=local_fit,
                                        prior=belief, max_steps=200 if method == "pem" else polish_steps,
                                        rounds=polish_rounds)
            now.outcome = f"{len(found.fixed_dict())} fixed"
        params = found.theta
        if local_fit == "output-error":
            fitted = output_error_problem(search, params)
    seconds = time.perf_counter() - t0
    if found is None:
        with stage("standard errors (Cramer-Rao) at the best parameters") as now:
            unc = standard_errors(fitted, params, nonfinite="unresolved")
            now.outcome = f"{int(np.sum(np.isfinite(unc.stderr) & (unc.stderr > 0)))} parameters resolved"
    else:
        unc = found.uncertainty
    record = {
        "method": method, "iterations": iterations, "trials": trials, "outputs": list(problem.outputs),
        "segment": settings.segment, "hold": settings.hold, "g": settings.g, "pem_segment": pem_segment,
        "lower": list(settings.lower), "upper": list(settings.upper),
        "cost": settings.cost, "polish_objective": polish_objective if method.endswith("+polish") else None,
        "polish_steps": polish_steps, "polish_rounds": polish_rounds, "cv_windows": cv_windows,
        "train_source": str(problem.source),
        "validate_source": None if validate is None else validate.source,
        "x64": bool(jax.config.jax_enable_x64), "search_precision": settings.precision,
        "engine_options": dict(engine_options or {}), "freq_options": dict(freq_options or {}),
        "frequency_skipped": skipped,
        "structure": bool(structure), "prior": None if prior is None else _describe_prior(prior),
        "prior_sd": None if prior is None else float(prior_sd),
        "evaluations": evaluations,
        "standard_errors": [part.sim.describe() for part in parts(fitted)],
    }
    truth = _known_truth(data) if truth is None else np.asarray(truth, dtype=np.float64)
    with stage("scores on the training flight" + ("" if validate is None else " and the validation flight")
               + ("" if truth is None else ", and the truth's beside them")):
        return IdentificationResult(
            method=method,
            seed=seed,
            settings=record,
            params=params,
            trial_params=trial_params,
            trial_costs=trial_costs,
            history=history,
            intervals95=intervals95(trial_params),
            stderr=dict(zip(PARAM_NAMES, map(float, unc.stderr))),
            train=scores(params, scored),
            validate=None if validate is None else validation_block(params, validate, problem),
            polish=polish_info,
            seconds=seconds,
            truth=None if truth is None else _truth_block(truth, unc, scored, validate, problem),
            frequency=None if fits is None else _frequency_block(fits, params),
            fixed=None if found is None else found.fixed_dict(),
            structure=None if found is None else {k: v for k, v in found.to_json().items() if k != "fixed"},
        )


def _local_fit(method: str, polish_objective: PolishObjective) -> LocalFit:
    """The least-squares fit the structure determination repeats for ``method``; raises where there is none."""
    if method == "pem":
        return "pem"
    if method.endswith("+polish") and polish_objective in ("output-error", "pem"):
        return polish_objective
    raise ValueError(f"identify: structure=True needs a least-squares fit to repeat: method 'pem' or a '+polish' "
                     f"method with polish_objective 'output-error' or 'pem' (got {method!r}, {polish_objective!r})")


def _describe_prior(prior: Any) -> str | list[float]:
    """How ``settings`` records the prior model: its name or file, else its 40 values."""
    if isinstance(prior, (str, Path)):
        return str(prior)
    return resolve_params(prior).tolist()


def scores(params: Float[np.ndarray, "40"], problem: Problem | Records) -> dict[str, Any]:
    """Metrics of ``params`` on ``problem``'s record (:func:`jaxheli.evaluate`): initial state estimated, and
    from rest under ``"zero_initial_state"`` (the paper's convention)."""
    block = evaluate(params, problem, x0="estimate")
    block["zero_initial_state"] = evaluate(params, problem, x0="zero")
    return block


def _population_trials(
    search: Problem | Records, engine_type: type, iterations: int, engine_options: dict[str, Any] | None, key,
    trials: int, run_options: dict[str, Any],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``trials`` runs of IWO or GA (vmapped when several) on ``search``'s population cost: each trial's best
    parameters ``[K, 40]``, cost ``[K]``, best cost per generation ``[K, iterations]``, and the candidates scored."""
    bounds = search.bounds
    engine = engine_type(lower=bounds.lower, upper=bounds.upper, iterations=iterations, **(engine_options or {}))
    keys = jax.random.split(key, trials)
    cost_fn = search.population_cost()
    run = (minimize_trials(engine, cost_fn, keys, **run_options) if trials > 1
           else minimize(engine, cost_fn, keys[0], **run_options))
    return (np.asarray(run.best_theta).reshape(trials, -1), np.asarray(run.best_cost).reshape(trials),
            np.asarray(run.history).reshape(trials, -1), int(np.sum(np.asarray(run.n_evaluations))))


def _cross_validation(
    data: FlightData, search: Problem | Records, trial_params: np.ndarray, trial_costs: np.ndarray,
    also: np.ndarray | None, count: int, steps: int, rounds: int, prior: Prior | None,
) -> CrossValidation:
    """The polish's run length and stopping round chosen by cross-validation on ``data``'s windows, from the best
    trial's starts."""
    best = int(np.argmin(trial_costs))
    starts = trial_params[best] if also is None else np.stack([trial_params[best], also[best]])
    found = cross_validate(data, search.settings, starts, count, rounds=rounds, max_steps=steps, prior=prior)
    note(f"cross-validation: {found.describe()}")
    return found


def _polish_trials(
    search: Problem | Records, trial_params: np.ndarray, trial_costs: np.ndarray, objective: PolishObjective,
    steps: int, rounds: int, also: np.ndarray | None = None, prior: Prior | None = None,
    chosen: CrossValidation | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Polish every trial (with ``also[k]``, a second start of trial ``k``, where given: the output-error polish's
    first round tries both; with the run length and stopping round ``chosen`` by cross-validation, where given);
    each trial's cost becomes its polished objective (the paper's cost for ``"pearson"``, else the normalised sum
    of squares per sample, :func:`jaxheli.cost.output_error_cost`)."""
    starts = trial_params if also is None else np.stack([trial_params, also], axis=1)
    schedule = {} if chosen is None else {"final": chosen.final, "stop": chosen.rounds}
    polished = []
    for k, th in enumerate(starts):
        with stage(f"polish of trial {k + 1} of {len(starts)} on the {objective} objective, "
                   + (f"up to {rounds} rounds of " if objective == "output-error" else "")
                   + f"{steps} LM steps") as now:
            polished.append(polish(th, search, objective=objective, max_steps=steps, rounds=rounds, prior=prior,
                                   **schedule))
            now.outcome = f"{polished[-1].n_steps} steps"
    costs = np.array([p.cost if objective == "pearson" else p.rss / search.n_samples for p in polished])
    before, after = int(np.argmin(trial_costs)), int(np.argmin(costs))
    search_costs = [search_cost_of(theta, search) for theta in (trial_params[before], polished[after].theta)]
    info = {
        "objective": objective,
        "params_before": dict(zip(PARAM_NAMES, map(float, trial_params[before]))),
        "cost_before": float(search_costs[0]),
        "cost_after": float(search_costs[1]),
        "objective_before": float(polished[before].cost_start if objective == "pearson"
                                  else polished[before].rss_start / search.n_samples),
        "objective_after": float(costs[after]),
        "steps": [p.n_steps for p in polished],
        "rounds": polished[after].settings.get("rounds"),
        "objective_rounds": _objective_rounds(polished[after], objective, search.n_samples),
        "cross_validation": None if chosen is None else chosen.to_json(),
    }
    return np.stack([p.theta for p in polished]), costs, info


def _objective_rounds(res: PEMResult, objective: PolishObjective, n_samples: int) -> list[list[float]]:
    """``[start, end]`` of the polish's objective in each of its rounds (one for ``"pearson"`` and ``"pem"``), on
    the scale of ``objective_before`` / ``objective_after``; the output-error polish's first rounds score shortened
    runs, so a round may start above where the one before ended."""
    if objective == "pearson":
        return [[float(res.cost_start), float(res.cost)]]
    rounds = res.settings.get("rounds") or [{"rss_start": res.rss_start, "rss": res.rss}]
    return [[float(r["rss_start"]) / n_samples, float(r["rss"]) / n_samples] for r in rounds]


def _frequency_trial(
    search: Problem | Records, start: np.ndarray | None, seed: int, k: int, trials: int,
    options: dict[str, Any] | None,
) -> FrequencyFitResult:
    """Trial ``k`` of ``trials``' frequency fit (:func:`~jaxheli.optim.frequency_fit.frequency_fit` from ``start``
    and draws of ``seed``, with ``options``), a stage of the progress lines."""
    with stage(f"frequency fit of trial {k + 1} of {trials} on Tischler's cost J") as now:
        fit = frequency_fit(search, start=start, seed=seed, **(options or {}))
        now.outcome = (f"average J {fit.j_average:.1f} from {fit.settings['starts']} starts of up to "
                       f"{fit.settings['max_steps']} LM steps")
    return fit


def _frequency_block(fits: list[FrequencyFitResult], params: Float[np.ndarray, "40"]) -> dict[str, Any]:
    """Tischler's ``J`` per pair at ``params`` on the frequency fit's bins, and the best trial's fit."""
    best = min(fits, key=lambda f: f.j_average)
    return {**cifer_report(best.targets, params), "fit": best.to_dict()}


_SETTING_OF = {"search_precision": "precision"}
"""``identify``'s argument names that differ from the :class:`~jaxheli.problem.Settings` field they set."""


def _refuse_conflicts(settings: Any, given: dict[str, Any]) -> None:
    """Raise a one-line ``ValueError`` naming every flight setting given to :func:`identify` beside a
    ``Problem`` that differs both from the argument's default and from the problem's own setting."""
    defaults = inspect.signature(identify).parameters
    clash = []
    for name, value in given.items():
        default, own = defaults[name].default, getattr(settings, _SETTING_OF.get(name, name))
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


def _pem_trials(
    problem: Problem | Records, key, trials: int, start, prior: Prior | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """PEM from the given start (or the middle of the box), plus random starts in the box for further trials."""
    mid = problem.bounds.midpoint() if start is None else np.asarray(start, dtype=np.float64)
    starts = [mid] + list(problem.bounds.uniform(k, 1)[0] for k in jax.random.split(key, trials - 1)) \
        if trials > 1 else [mid]
    fits = [pem(problem, start=s, prior=prior) for s in starts]
    return np.stack([f.theta for f in fits]), np.array([f.cost for f in fits])
