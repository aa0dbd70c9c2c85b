"""Write an identification result to a folder: ``result.json``, ``result.npz``, the flights as fitted (NPZ)
and PNG plots."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ._progress import stage
from .at_bounds import AtBound, at_bounds
from .data.flight import FlightData
from .data.flight import default_outputs
from .evaluate import simulate_as_scored
from .identify import IdentificationResult
from .io.npz import save_npz
from .model import G_SI, INPUT_NAMES, LOWER, PARAM_NAMES, UPPER, params_array
from .modes import Mode, modes
from .optim.frequency_fit import model_step
from .plots import PRIMARY_PAIRS, plot_convergence, plot_frequency_response, plot_time_domain
from .spectra import estimate_frequency_response, model_frequency_response

PLOT_CHANNELS: tuple[str, ...] = ("p", "q", "phi", "theta")
"""Channels of the time-domain verification plots (the paper's Figs. 4-6)."""
FLIGHT_FILES: dict[str, str] = {"train": "train_flight.npz", "validate": "validate_flight.npz"}
"""File names, inside a result folder, of the flights exactly as fitted and scored (after preprocessing; their
``metadata["preprocessing"]`` says what was done to the source file). ``result.json``'s ``data`` block names
them, and ``jaxheli report`` reads them rather than the raw source files."""


def result_modes(result: IdentificationResult) -> tuple[Mode, ...]:
    """The identified model's modes (:func:`jaxheli.modes.modes` under the result's gravity)."""
    return modes(result.params, result.settings.get("g", G_SI))


def result_at_bounds(result: IdentificationResult) -> tuple[AtBound, ...]:
    """The identified parameters on a bound of the search box (:func:`jaxheli.at_bounds.at_bounds`): the box the
    settings record, else the authors'; parameters the model-structure determination fixed (``result.fixed``) are
    listed there instead, even when the value they are held at is a bound."""
    found = at_bounds(result.params, result.settings.get("lower", LOWER), result.settings.get("upper", UPPER))
    return tuple(a for a in found if a.name not in (result.fixed or {}))


def _verification(result: IdentificationResult, flight: FlightData, x0, path: Path, title: str) -> Path:
    """Plot ``PLOT_CHANNELS`` as the result was scored on ``flight``, from ``x0`` (``"estimate"``, ``"zero"``),
    with the truth's response beneath when it is known."""
    scored = tuple(c for c in result.settings["outputs"] if c in flight.output_names) or default_outputs(flight)
    chans = tuple(c for c in PLOT_CHANNELS if c in scored) or scored
    truth = {} if result.truth is None else {
        "truth": simulate_as_scored(result.truth["parameters"], result.settings, flight, chans, x0)}
    models = {**truth, result.method: simulate_as_scored(result.params, result.settings, flight, chans, x0)}
    return plot_time_domain(flight.time, flight.select(chans).outputs, models, chans, path, title)


def _frequency(result: IdentificationResult, flight: FlightData, path: Path) -> Path:
    """Flight against model frequency responses on the on-axis pairs of the frequency fit's band, the truth's
    beside when it is known, each pair's J (at the result) in its title."""
    fit = result.frequency["fit"]["settings"]
    chans = tuple(c for c in result.settings["outputs"] if c in flight.output_names)
    estimate = estimate_frequency_response(flight.inputs, flight.select(chans).outputs, flight.dt,
                                           segment_seconds=fit["segment_s"][0])
    dt = model_step(result.settings["hold"], flight.dt)
    params = {} if result.truth is None else {"truth": params_array(result.truth["parameters"])}
    params[result.method] = result.params
    models = {label: np.asarray(model_frequency_response(th, estimate.freq, chans, result.settings["g"], dt))
              for label, th in params.items()}
    costs = {tuple(name.split("->")): f"J {j:.0f}" for name, j in result.frequency["j"].items() if "(" not in name}
    pairs = [p for p in PRIMARY_PAIRS if p[1] in chans] or [(i, chans[0]) for i in INPUT_NAMES]
    return plot_frequency_response(estimate, models, chans, path, pairs=pairs, band=tuple(fit["band_hz"]),
                                   min_coherence=fit["min_coherence"], notes=costs,
                                   title=f"{result.method}: flight against model frequency responses")


def save_result(
    result: IdentificationResult,
    out_dir: str | Path,
    train: FlightData | Sequence[FlightData],
    validate: FlightData | None = None,
) -> list[Path]:
    """Save ``result`` under ``out_dir``; returns the files written.

    Writes ``result.json`` (with each flight's source, preprocessing steps and load warnings under
    ``provenance``, the model's ``modes`` (:func:`result_modes`), the parameters on a bound, ``at_bounds``
    (:func:`result_at_bounds`), and those the model-structure determination fixed, ``fixed``
    (``{name: {value, reason, ...}}``, ``null`` when it did not run)), ``result.npz``, ``train_flight.npz`` / ``validate_flight.npz`` (the flights as the
    fit and the scores saw them; further training records as ``train_flight_2.npz``, ... listed in
    ``data["train_records"]``) and the PNG plots (time-domain verification per record, convergence with the polish rounds, and for the
    frequency methods flight against model frequency responses).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    records = [train] if isinstance(train, FlightData) else list(train)
    names = [_numbered(FLIGHT_FILES["train"], k) for k in range(len(records))]
    files = [out / "result.json", out / "result.npz"]
    files += [save_npz(f, out / name) for f, name in zip(records, names)]
    content = result.to_json()
    content["modes"] = [m.to_json() for m in result_modes(result)]
    content["at_bounds"] = [a.to_json() for a in result_at_bounds(result)]
    content["data"] = {"train": names[0]}
    if len(records) > 1:
        content["data"]["train_records"] = names
    if validate is not None:
        files.append(save_npz(validate, out / FLIGHT_FILES["validate"]))
        content["data"]["validate"] = FLIGHT_FILES["validate"]
    flights = {("train" if k == 0 else f"train_{k + 1}"): f for k, f in enumerate(records)}
    if validate is not None:
        flights["validate"] = validate
    content["provenance"] = {role: {"source": f.source, "preprocessing": f.metadata.get("preprocessing", []),
                                    "warnings": f.metadata.get("warnings", [])} for role, f in flights.items()}
    files[0].write_text(json.dumps(content, indent=2, default=str))
    np.savez(
        files[1],
        params=result.params,
        param_names=np.array(PARAM_NAMES),
        trial_params=result.trial_params,
        trial_costs=result.trial_costs,
        history=result.history,
        stderr=np.array([result.stderr[n] for n in PARAM_NAMES]),
    )
    with stage(f"plots in {out}"):
        for k, flight in enumerate(records):
            files.append(_verification(result, flight, "estimate", out / _numbered("verification_train.png", k),
                                       f"{result.method}: training flight{f' {k + 1}' if len(records) > 1 else ''}"
                                       " (initial state estimated)"))
        if validate is not None:
            files.append(
                _verification(result, validate, "estimate", out / "verification_validate.png",
                              f"{result.method}: validation flight (initial state estimated)")
            )
        if result.frequency is not None:
            files.append(_frequency(result, records[0], out / "frequency_response.png"))
        polished = (result.polish or {}).get("objective_rounds")
        if result.history.size or polished:
            curves = {f"trial {k}": h for k, h in enumerate(result.history) if h.size}
            rounds = {f"polish ({result.polish['objective']})": polished} if polished else None
            files.append(plot_convergence(curves, out / "convergence.png", f"{result.method} convergence", rounds))
    return files


def _numbered(name: str, k: int) -> str:
    """``name`` for the first of several files, ``stem_{k+1}.suffix`` for the others."""
    path = Path(name)
    return name if k == 0 else f"{path.stem}_{k + 1}{path.suffix}"
