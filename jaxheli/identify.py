"""One entry point for every identification method: IWO, GA, PEM, IWO + gradient polish.

``identify(flight, method=...)`` runs the chosen engine (K trials vmapped in one scan for the population
methods), polishes when asked, computes Cramer-Rao standard errors and 95 % intervals over trials, and
scores the result on the training flight and, if given, a validation flight. The result object holds
everything :func:`jaxheli.identify_report.save_result` writes (JSON, NPZ, PNG).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.stats

from ._types import Array, Float
from .sim.population import simulator_cost
from .evaluate import default_outputs, evaluate
from .data.flight import FlightData
from .model import G_SI, LOWER, PARAM_NAMES, UPPER
from .optim.ga import GA
from .optim.iwo import IWO
from .optim.pem import pem
from .optim.polish import polish
from .optim.run import minimize, minimize_trials
from .optim.uncertainty import standard_errors
from .sim.simulate import Simulator, make_simulator

Method = Literal["iwo", "ga", "pem", "iwo+polish"]
METHODS: tuple[str, ...] = ("iwo", "ga", "pem", "iwo+polish")


class _PopulationCost(eqx.Module):
    """``thetas[P, 40] -> cost[P]`` on one flight, scored in ``dtype`` (the fastest kernel the simulator
    has, :func:`jaxheli.sim.population.simulator_cost`); a pytree, so the flight stays traced inside the scan."""

    sim: Simulator
    target: Float[Array, "N k"]
    dtype: str = eqx.field(static=True)

    def __call__(self, thetas: Float[Array, "P 40"]) -> Float[Array, "P"]:
        cost = simulator_cost(self.sim, thetas.astype(self.dtype), self.target.astype(self.dtype))
        return cost.astype(thetas.dtype)


@dataclasses.dataclass
class IdentificationResult:
    """What an identification run produced.

    Attributes:
        method, seed: how it was run; ``settings`` holds every other choice (simulation included).
        params: ``[40]`` the identified parameters (best trial, polished when the method says so).
        trial_params, trial_costs: ``[K, 40]`` and ``[K]`` each trial's final parameters and training cost.
        history: ``[K, iterations]`` best cost per generation (population methods; empty for PEM).
        intervals95: ``{name: (low, high)}`` t-interval of the trial mean (``None`` for one trial).
        stderr: ``{name: value}`` Cramer-Rao standard errors at ``params`` (inf: not identifiable).
        train, validate: metric blocks of :func:`jaxheli.evaluate` (``validate`` ``None`` without a flight);
            ``validate["zero_initial_state"]`` repeats the scores from rest, the paper's convention.
        polish: the best unpolished parameters and the cost before and after the gradient polish
            (``None`` unless polished).
        seconds: wall time of the fit.
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
    flight: FlightData,
    *,
    method: Method = "iwo+polish",
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
    polish_steps: int = 100,
    pem_segment: float = 5.0,
    search_precision: Literal["float32", "float64"] = "float32",
    engine_options: dict[str, Any] | None = None,
    chunk: int = 50,
    checkpoint: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> IdentificationResult:
    """Identify the 40 hover-model parameters from ``flight``.

    Args:
        flight: training record.
        method: ``"iwo"``, ``"ga"``, ``"pem"`` or ``"iwo+polish"`` (IWO, then optimistix on the same cost).
        validate: optional held-out record, scored with an estimated initial state and from rest.
        iterations: generations of IWO / GA (the paper: 1000).
        trials: independent trials (vmapped); their spread gives the 95 % intervals (the paper: 10).
        seed: PRNG seed; the run is a deterministic function of it.
        outputs: channels of the cost (default: the flight's measured channels without a, b).
        segment: restart interval of the simulation, s (``None``: the paper's single run from rest).
        hold, g: simulation settings (:func:`jaxheli.make_simulator`).
        lower, upper: search box of the population methods (default: the authors' bounds).
        start: PEM's start (default: the middle of the bounds; random in the box for trials > 1).
        polish_steps: Levenberg-Marquardt steps of the polish.
        pem_segment: predictor restart interval of PEM, s (keeps unstable candidates usable).
        search_precision: arithmetic of the IWO / GA population scoring (float32, the default, is several
            times faster and its costs agree with float64 to 1e-3, see ``tests/test_blocked.py``); the polish,
            PEM and every reported metric run in the session's precision (float64 unless disabled).
        engine_options: further hyperparameters of :class:`~jaxheli.optim.IWO` / :class:`~jaxheli.optim.GA`
            (e.g. ``{"modulation": 3.0}``; default: the paper's settings).
        chunk, checkpoint, resume, progress: run control of :func:`jaxheli.optim.run.minimize`.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if trials < 1 or iterations < 1:
        raise ValueError(f"trials and iterations must be >= 1, got {trials}, {iterations}")
    names = tuple(outputs) if outputs is not None else default_outputs(flight)
    sim_options = {"outputs": names, "segment": segment, "hold": hold, "g": g}
    t0 = time.perf_counter()
    key = jax.random.PRNGKey(seed)
    history = np.zeros((trials, 0))
    polish_info = None
    if method == "pem":
        trial_params, trial_costs = _pem_trials(flight, key, trials, start, names, pem_segment, hold, g)
        fit_options = {"outputs": names, "segment": pem_segment, "hold": hold, "g": g, "x0": "measured"}
    else:
        sim = make_simulator(flight, x0="zero", **sim_options)
        cost_fn = _PopulationCost(sim, jnp.asarray(flight.select(names).outputs), search_precision)
        engine_type = IWO if method != "ga" else GA
        engine = engine_type(lower=lower, upper=upper, iterations=iterations, **(engine_options or {}))
        keys = jax.random.split(key, trials)
        run = (
            minimize_trials(engine, cost_fn, keys, chunk=chunk, progress=progress, checkpoint=checkpoint, resume=resume)
            if trials > 1
            else minimize(engine, cost_fn, keys[0], chunk=chunk, progress=progress, checkpoint=checkpoint, resume=resume)
        )
        trial_params = np.asarray(run.best_theta).reshape(trials, -1)
        trial_costs = np.asarray(run.best_cost).reshape(trials)
        history = np.asarray(run.history).reshape(trials, -1)
        fit_options = {**sim_options, "x0": "zero"}
        if method == "iwo+polish":
            polished = [polish(th, flight, max_steps=polish_steps, x0="zero", **sim_options) for th in trial_params]
            best_before = int(np.argmin(trial_costs))
            polish_info = {
                "params_before": dict(zip(PARAM_NAMES, map(float, trial_params[best_before]))),
                "cost_before": float(trial_costs[best_before]),
                "cost_after": float(min(p.cost for p in polished)),
                "steps": [p.n_steps for p in polished],
            }
            trial_params = np.stack([p.theta for p in polished])
            trial_costs = np.array([p.cost for p in polished])
    best = int(np.argmin(trial_costs))
    params = trial_params[best]
    seconds = time.perf_counter() - t0
    unc = standard_errors(flight, params, **fit_options)
    settings = {
        "method": method, "iterations": iterations, "trials": trials, "outputs": list(names),
        "segment": segment, "hold": hold, "g": g, "pem_segment": pem_segment, "polish_steps": polish_steps,
        "train_source": flight.source, "validate_source": None if validate is None else validate.source,
        "x64": bool(jax.config.jax_enable_x64), "search_precision": search_precision,
        "engine_options": dict(engine_options or {}),
    }
    train_block = evaluate(params, flight, x0=fit_options["x0"], **{k: v for k, v in fit_options.items() if k != "x0"})
    return IdentificationResult(
        method=method,
        seed=seed,
        settings=settings,
        params=params,
        trial_params=trial_params,
        trial_costs=trial_costs,
        history=history,
        intervals95=intervals95(trial_params),
        stderr=dict(zip(PARAM_NAMES, map(float, unc.stderr))),
        train=train_block,
        validate=None if validate is None else validation_block(params, validate, names, hold=hold, g=g, segment=segment),
        polish=polish_info,
        seconds=seconds,
    )


def validation_block(
    params: Float[np.ndarray, "40"], flight: FlightData, outputs: tuple[str, ...], **options
) -> dict[str, Any]:
    """Scores on a held-out flight: initial state estimated (default) and from rest (the paper)."""
    chans = tuple(c for c in outputs if c in flight.output_names) or default_outputs(flight)
    block = evaluate(params, flight, outputs=chans, x0="estimate", **options)
    block["zero_initial_state"] = evaluate(params, flight, outputs=chans, x0="zero", **options)
    return block


def _pem_trials(flight, key, trials, start, names, segment, hold, g) -> tuple[np.ndarray, np.ndarray]:
    """PEM from the given start (or the middle of the box), plus random starts for further trials."""
    mid = (LOWER + UPPER) / 2 if start is None else np.asarray(start, dtype=np.float64)
    starts = [mid] + [
        LOWER + (UPPER - LOWER) * np.asarray(jax.random.uniform(k, (len(PARAM_NAMES),)))
        for k in jax.random.split(key, trials - 1)
    ] if trials > 1 else [mid]
    fits = [pem(flight, start=s, outputs=names, segment=segment, hold=hold, g=g) for s in starts]
    return np.stack([f.theta for f in fits]), np.array([f.cost for f in fits])
