"""How far the gap shrinks: the whole diagnosis of a model on a training and a validation flight, and its files
(what ``jaxheli diagnose`` writes; the command line words it on the console).

Composes the pieces of :mod:`jaxheli.gap`: the data-consistency findings of both flights
(:func:`~jaxheli.gap.consistency.check`), where the base model misses the validation flight
(:func:`~jaxheli.gap.compare.localise_prediction`), and the candidate effects fitted on the training flight
and ranked by their shrink of the validation gap (:func:`~jaxheli.gap.ranking.diagnose_effects`).

Every gap here is the segment-wise predictor's (:mod:`jaxheli.gap.predictor`: restarts from the
Kalman-filtered state every ``segment`` s, zero-order hold), so the localised residual, ``gap_before`` and the ranking's
base gap are one and the same number.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._progress import stage
from .._types import Array, Float
from ..cost import nmse
from ..evaluate import resolve_params
from ..data.flight import FlightData, constant_outputs
from ..problem import make_problem
from ..bounds import Bounds
from ..model import G_SI, MEASURABLE
from ..effects import registry as fx
from ..effects.plant import no_effect
from .consistency import check, correct as fix
from .compare import frequency_comparison, localise_prediction
from .localisation_record import Localisation
from .fit_effect import MAX_STEPS, effect_eta as effect_eta
from .predictor import RESTART, SEGMENT, Predictor, make_predictor, smooths
from .prepare import SAMPLE_S, at_step
from .ranking import diagnose_effects, predictor_pair
from .records import Diagnosis, Entry, FlightSummary, Gap
from .significance import MIN_SHRINK

_NOT_STATES = ("a", "b")
"""Flapping columns of the real logs: stick multiples, never diagnosed."""


def shared_outputs(train: FlightData, validate: FlightData) -> tuple[str, ...]:
    """Channels both flights carry that the model measures (``a``, ``b`` excluded) and that move on both
    (a constant channel, e.g. velocities a log filled with zeros, carries no information), in ``train``'s
    order."""
    flat = set(constant_outputs(train)) | set(constant_outputs(validate))
    names = tuple(c for c in train.output_names
                  if c in validate.output_names and c in MEASURABLE and c not in _NOT_STATES and c not in flat)
    if not names:
        raise ValueError(f"{train.source} {train.output_names} and {validate.source} {validate.output_names} "
                         f"share no model output channel that varies")
    return names


@eqx.filter_jit
def _predict(pred: Predictor, thetas: Float[Array, "C 40"], etas: Float[Array, "C E"]) -> Float[Array, "C N k"]:
    return jax.vmap(pred)(thetas, etas)


def predictions(
    theta: Float[np.ndarray, "40"], pred: Predictor, entries: Sequence[Entry],
) -> Float[np.ndarray, "C+1 N k"]:
    """Predicted outputs of the base model ``theta`` (first) and of each ranking entry's fitted effect with the
    base parameters fitted with it on ``pred``'s flight (all its channels), by the segment-wise predictor the
    ranking scores with (:func:`~jaxheli.gap.ranking.predictor_pair`)."""
    etas = [no_effect(pred.outputs)] + [effect_eta(e.effect, e.fitted.params, pred.outputs, e.nuisance)
                                        for e in entries]
    thetas = [np.asarray(theta, np.float64)] + [e.theta for e in entries]
    return np.asarray(_predict(pred, jnp.asarray(np.stack(thetas)), jnp.asarray(np.stack(etas))))


def diagnose(
    model,
    train: FlightData,
    validate: FlightData,
    *,
    name: str | None = None,
    outputs: Sequence[str] | None = None,
    effects: Sequence[str] = fx.ALL,
    segment: float = SEGMENT,
    restart: str = RESTART,
    top: int = 3,
    g: float = G_SI,
    localise_train: bool = True,
    track: float | None = None,
    joint: bool = True,
    bounds: Bounds | None = None,
    max_steps: int = MAX_STEPS,
    min_shrink: float = MIN_SHRINK,
    dt: float | None = SAMPLE_S,
    correct: bool = False,
) -> Diagnosis:
    """The diagnosis of ``model`` (anything :func:`jaxheli.resolve_params` takes; the record calls it ``name``,
    default the file or set name ``model`` is, else ``"given parameters"``).

    Effects are fitted on ``train`` jointly with the base parameters in ``bounds`` (``joint=False``: the base
    model held fixed) and scored on ``validate`` (:func:`~jaxheli.gap.ranking.diagnose_effects`, with ``top``,
    ``max_steps`` and ``min_shrink``); ``segment`` (s) is the restart interval of every prediction, ``restart``
    where it restarts (:data:`~jaxheli.gap.predictor.RESTARTS`) and ``track`` the restart filter's level (``None``:
    tuned on ``train``). ``outputs`` default to :func:`shared_outputs`; ``localise_train`` localises the training
    flight's gap too. A flight sampled faster than ``dt`` (s; default the thresholds' step, that of the flights they
    were set on) is low-passed and resampled to it first (:func:`~jaxheli.gap.prepare.at_step`; ``None``: each at
    its own step). Each flight is checked for consistency once (:func:`~jaxheli.gap.consistency.check`), and with
    ``correct`` its significant findings are applied before any fit (:func:`~jaxheli.gap.consistency.correct`).
    """
    smooth = smooths(restart, "diagnose")
    theta = resolve_params(model)
    if name is None:
        name = str(model) if isinstance(model, (str, Path)) else "given parameters"
    names = tuple(outputs) if outputs is not None else shared_outputs(train, validate)
    _check_outputs(names, train, validate)
    flights = {"train": at_step(train.select(names), dt), "validate": at_step(validate.select(names), dt)}
    with stage("consistency check of both flights" + (", significant findings corrected" if correct else "")) as now:
        findings = {role: check(flight) for role, flight in flights.items()}
        if correct:
            flights = {role: at_step(fix(flight, findings[role]), dt) for role, flight in flights.items()}
        consistency = tuple({**f.to_json(), "flight": role} for role, found in findings.items() for f in found)
        now.outcome = f"{sum(f['significant'] for f in consistency)} significant of {len(consistency)} findings"
    train, validate = flights["train"], flights["validate"]
    problems = [make_problem(f, outputs=names, g=g) for f in (train, validate)]
    with stage("predictors of both flights" + (", the restart filter tuned on the training flight"
                                               if track is None else "")) as now:
        preds = predictor_pair(theta, *problems, segment=segment, g=g, track=track, smooth=smooth)
        now.outcome = f"restart filter level {float(preds[0].track):g}"
    attribution = diagnose_effects(theta, *preds, list(effects), top=top, joint=joint, bounds=bounds,
                                   max_steps=max_steps, min_shrink=min_shrink)
    with stage("gaps and localisation of the base model" + (" on both flights" if localise_train else "")):
        gaps = [_gap(gap, names) for gap in np.asarray(nmse(predictions(theta, preds[1], attribution.shown),
                                                              validate.outputs))]
        return Diagnosis(
            model=name,
            flights={role: _flight_summary(f) for role, f in (("train", train), ("validate", validate))},
            outputs=names,
            segment_s=segment,
            restart=restart,
            consistency=consistency,
            localisation=_localise_base(theta, validate, preds[1], segment, restart),
            attribution=attribution,
            gap_before=gaps[0],
            gap_best=gaps[1],
            gap_combination=gaps[2] if len(gaps) > 2 else None,
            localisation_train=_localise_base(theta, train, preds[0], segment, restart) if localise_train else None,
            validated=validate,
        )


def _check_outputs(names: tuple[str, ...], train: FlightData, validate: FlightData) -> None:
    """Errors for channels ``names`` a flight lacks, that are no model state the diagnosis uses, or are constant."""
    for role, flight in (("train", train), ("validate", validate)):
        missing = [c for c in names if c not in flight.output_names]
        if missing:
            raise ValueError(f"{flight.source} ({role} flight): no output channel(s) {missing}; it has "
                             f"{flight.output_names}")
    bad = [c for c in names if c in _NOT_STATES or c not in MEASURABLE]
    if bad:
        raise ValueError(f"diagnose: output channel(s) {bad} are not model states the diagnosis can use")
    for role, flight in (("train", train), ("validate", validate)):
        flat = [c for c in names if c in constant_outputs(flight)]
        if flat:
            raise ValueError(f"{flight.source} ({role} flight): output channel(s) {flat} are constant; leave "
                             f"them out of outputs")


def _localise_base(
    theta: Float[np.ndarray, "40"], flight: FlightData, pred: Predictor, segment: float, restart: str,
) -> Localisation:
    """Where the base model's segment-wise prediction ``pred`` (restarts every ``segment`` s, ``restart``:
    :data:`~jaxheli.gap.predictor.RESTARTS`) misses ``flight`` (:func:`localise_prediction`)."""
    base = predictions(theta, pred, [])[0]
    simulation = {"predictor": f"segment-wise, restarts from the Kalman-filtered state{_RESTARTED[restart]} "
                               "(jaxheli.gap.predictor)",
                  "segment": segment, "restart": restart, "track": float(pred.track), "g": pred.g, "hold": "zoh"}
    return localise_prediction(theta, flight, base, flight.output_names, simulation)


_RESTARTED = {"filter": "", "segment": " re-estimated from each segment's readings"}
"""How each restart is described in the localisation's ``simulation``."""


def _gap(gap: np.ndarray, names: tuple[str, ...]) -> Gap:
    return Gap(dict(zip(names, map(float, gap))), float(np.mean(gap)))


def _flight_summary(flight: FlightData) -> FlightSummary:
    return FlightSummary(flight.source, flight.n_samples, flight.dt,
                         tuple(flight.metadata.get("preprocessing", [])))


def write_diagnosis(
    diagnosis: Diagnosis, theta: Float[np.ndarray, "40"], validate: FlightData, out: str | Path,
) -> list[Path]:
    """Write ``diagnosis.json`` (:meth:`~jaxheli.gap.records.Diagnosis.to_json`), ``consistency.json`` and the PNGs
    (residual bands, lag correlation, frequency response, before/after time histories on the validation flight as
    diagnosed, ``diagnosis.validated``, or on ``validate`` for a diagnosis read back from JSON) into ``out``."""
    from ..plots import plot_frequency_response
    from .plots import plot_before_after, plot_lag_correlation, plot_residual_bands

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = diagnosis.outputs
    flight = diagnosis.validated if diagnosis.validated is not None else validate.select(names)
    content = diagnosis.to_json()
    local = diagnosis.localisation
    g = local.simulation["g"]
    (out / "diagnosis.json").write_text(json.dumps(content, indent=1))
    (out / "consistency.json").write_text(json.dumps(content["consistency"], indent=1))
    shown = diagnosis.attribution.shown
    with stage(f"plots in {out}"):
        pred = make_predictor(flight, segment=diagnosis.segment_s, g=g, track=diagnosis.attribution.track,
                              smooth=smooths(diagnosis.restart, str(out)))
        estimate, model = frequency_comparison(theta, flight, names, g)
        return [
            out / "diagnosis.json",
            out / "consistency.json",
            plot_residual_bands(local, out / "residual_bands.png", title=flight.source),
            plot_lag_correlation(local, out / "lag_correlation.png"),
            plot_frequency_response(estimate, model, names, out / "frequency_response.png", title=flight.source),
            plot_before_after(flight, predictions(theta, pred, shown),
                              ["base model"] + [f"+ {e.effect}" for e in shown], out / "before_after.png"),
        ]
