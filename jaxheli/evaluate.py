"""Score a parameter set on a flight: Pearson, TIC, RMSE, fit % per channel and the paper's cost."""

from __future__ import annotations

import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from ._types import Array, Float
from ._xla import quick_jit
from .cost import metrics, search_cost
from .data.flight import FlightData
from .model import G_SI, N_PARAMS, N_STATES, PARAM_NAMES, TABLE2, params_array
from .problem import Problem, Records, as_problem, make_problem, parts
from .sim.discretize import Hold
from .sim.initial_state import Start, estimate_start, estimate_x0
from .sim.simulate import Simulator

NAMED_MODELS = {"table2": TABLE2}
"""Parameter sets a user can name instead of a file (SI units)."""


def resolve_params(spec: str | Path | np.ndarray | dict) -> Float[np.ndarray, "40"]:
    """A parameter vector from a name (``"table2"``), a result/params JSON file, a dict or an array."""
    if isinstance(spec, np.ndarray) or (isinstance(spec, (list, tuple)) and len(spec) == N_PARAMS):
        theta = np.asarray(spec, dtype=np.float64)
    elif isinstance(spec, dict):
        theta = params_array(spec.get("parameters", spec))
    elif str(spec).lower() in NAMED_MODELS:
        theta = NAMED_MODELS[str(spec).lower()].copy()
    else:
        path, content = Path(spec), _model_file(spec)
        values = content.get("parameters", content) if isinstance(content, dict) else None
        if not isinstance(values, dict):
            raise ValueError(f"{path}: field 'parameters': expected a {{name: value}} object of the 40 parameters")
        try:
            theta = params_array(values)
        except ValueError as err:
            raise ValueError(f"{path}: field 'parameters': {err}") from None
    if theta.shape != (N_PARAMS,) or not np.isfinite(theta).all():
        raise ValueError(f"model parameters must be 40 finite numbers ({', '.join(PARAM_NAMES[:3])}, ...)")
    return theta


def recorded_hold(spec: str | Path | np.ndarray | dict) -> Hold | None:
    """The input hold an identification result (a ``result.json`` or its dict) was fitted and scored with,
    ``None`` for anything else (a named model, bare parameters, an array)."""
    if isinstance(spec, dict):
        content = spec
    elif isinstance(spec, (str, Path)) and str(spec).lower() not in NAMED_MODELS:
        content = _model_file(spec)
    else:
        return None
    hold = content.get("settings", {}).get("hold") if isinstance(content, dict) else None
    return hold if hold in ("zoh", "foh") else None


def _model_file(spec: str | Path) -> object:
    """The JSON content of a model file, with a one-line error naming the file when it is missing or not JSON."""
    path = Path(spec)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such model file (or a named model: {sorted(NAMED_MODELS)})")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not a JSON model file ({err})") from None


def evaluate(
    params: str | Path | np.ndarray | dict,
    data: FlightData | Problem | Records | list[FlightData],
    *,
    outputs: tuple[str, ...] | list[str] | None = None,
    x0: str | np.ndarray = "estimate",
    **options,
) -> dict[str, object]:
    """Metrics of one parameter set on a record.

    Args:
        params: anything :func:`resolve_params` takes.
        data: the record to score on: a flight, or a :class:`~jaxheli.problem.Problem` (its channels and
            simulation settings; ``outputs`` and ``options`` then change its settings as a variant); several
            flights or a :class:`~jaxheli.problem.Records` are scored together, each record simulated from its
            own initial state and the records' samples pooled.
        outputs: channels to score (default :func:`~jaxheli.data.flight.default_outputs`).
        x0: ``"estimate"`` (least-squares initial state, as MATLAB ``compare``), ``"zero"`` (the paper),
            ``"measured"``, or a 13-vector.
        options: simulation settings (:class:`~jaxheli.problem.Settings` fields: ``hold``, ``g``, ``segment``);
            scoring flights, the hold defaults to the one a result's ``params`` were fitted with
            (:func:`recorded_hold`).

    Returns ``{"pearson": {ch: rho}, "tic": ..., "rmse": ..., "fit_percent": ..., "cost": C,
    "simulation": settings}``.
    """
    theta = resolve_params(params)
    if options.get("hold") is None and not isinstance(data, (Problem, Records)):
        options = {k: v for k, v in options.items() if k != "hold"} | {"hold": recorded_hold(params) or "zoh"}
    problem = as_problem(data, outputs=outputs, **options)
    records = parts(problem)
    sims = [started_simulator(part, theta, x0) for part in records]
    y = np.concatenate([np.asarray(_outputs(sim, jnp.asarray(theta))) for sim in sims])
    out = metrics(y, np.concatenate([np.asarray(part.target) for part in records]), problem.outputs)
    settings = sims[0].describe()
    settings["initial_state"] = x0 if isinstance(x0, str) else "given"
    settings["records"] = len(records)
    out["simulation"] = settings
    return out


def search_cost_of(params: Float[np.ndarray, "40"], problem: Problem | Records) -> float:
    """``problem``'s search cost (:func:`jaxheli.cost.search_cost` of its settings) of one parameter vector,
    simulated from rest in the session's precision (the program :func:`evaluate` compiles for ``x0="zero"``);
    summed over records."""
    theta = jnp.asarray(params)
    return sum(float(search_cost(part.settings.cost, _outputs(started_simulator(part, theta, "zero"), theta),
                                 part.target)) for part in parts(problem))


@quick_jit
def _outputs(sim: Simulator, theta: Float[Array, "40"]) -> Float[Array, "N k"]:
    """``sim(theta)`` as one program compiled for a single run."""
    return sim(theta)


def started_simulator(problem: Problem, theta: Float[np.ndarray, "40"], x0: str | np.ndarray) -> Simulator:
    """``problem``'s simulator started from ``x0``: ``"estimate"`` (least squares for ``theta``,
    :func:`~jaxheli.sim.initial_state.estimate_x0`), ``"zero"``, ``"measured"`` or a 13-vector."""
    if isinstance(x0, str) and x0 == "estimate":
        return problem.sim.replace_x0(estimate_x0(theta, problem))
    if isinstance(x0, str) and x0 == "zero":  # as a given state: the estimated start's compiled program serves it
        return problem.sim.replace_x0(np.zeros(N_STATES))
    if isinstance(x0, str):
        return problem.variant(x0=x0).sim
    return problem.sim.replace_x0(np.asarray(x0))


def biased_start_outputs(problem: Problem, theta: Float[np.ndarray, "40"]) -> tuple[Start, Float[np.ndarray, "N k"]]:
    """``problem``'s outputs ``[N, k]`` under ``theta`` from the least-squares start with a per-channel output bias
    (:func:`~jaxheli.sim.initial_state.estimate_start`, ``bias=True``), and that start: a run of time-domain
    verification."""
    start = estimate_start(theta, problem, bias=True)
    y = _outputs(started_simulator(problem, theta, start.x0), jnp.asarray(theta))
    return start, np.asarray(y) + start.bias


def simulate_as_scored(
    params: str | Path | np.ndarray | dict,
    settings: dict,
    flight: FlightData,
    channels: tuple[str, ...] | list[str],
    x0: str | np.ndarray = "estimate",
) -> Float[np.ndarray, "N k"]:
    """Outputs ``[N, k]`` for ``channels`` of ``params`` on ``flight``, simulated as an identification result
    with ``settings`` was scored: its hold, g, segment and scored channels (``settings["outputs"]``, when
    they include ``channels``, so the simulator compiled for the scores serves plots too), from ``x0`` as in
    :func:`evaluate`."""
    theta = resolve_params(params)
    scored = tuple(c for c in settings.get("outputs") or () if c in flight.output_names)
    names = scored if set(channels) <= set(scored) else tuple(channels)
    problem = make_problem(flight, outputs=names, hold=settings.get("hold", "zoh"), g=settings.get("g", G_SI),
                           segment=settings.get("segment"))
    y = np.asarray(started_simulator(problem, theta, x0)(theta))
    return y[:, [names.index(c) for c in channels]]
