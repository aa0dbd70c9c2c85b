"""Write an identification result to a folder: ``result.json``, ``result.npz`` and PNG plots."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .flight import FlightData
from .identify import IdentificationResult
from .initial_state import estimate_x0
from .model import PARAM_NAMES
from .plots import plot_convergence, plot_time_domain
from .simulate import make_simulator

PLOT_CHANNELS: tuple[str, ...] = ("p", "q", "phi", "theta")
"""Channels of the time-domain verification plots (the paper's Figs. 4-6)."""


def _verification(result: IdentificationResult, flight: FlightData, x0, path: Path, title: str) -> Path:
    chans = tuple(c for c in PLOT_CHANNELS if c in flight.output_names) or flight.output_names
    opts = {"outputs": chans, "hold": result.settings["hold"], "g": result.settings["g"]}
    if isinstance(x0, str) and x0 == "estimate":
        x0 = estimate_x0(result.params, flight, **opts)
    sim = make_simulator(flight, x0=x0, segment=result.settings["segment"], **opts)
    y = np.asarray(sim(result.params))
    return plot_time_domain(flight.time, flight.select(chans).outputs, {result.method: y}, chans, path, title)


def save_result(
    result: IdentificationResult, out_dir: str | Path, train: FlightData, validate: FlightData | None = None
) -> list[Path]:
    """Save ``result`` under ``out_dir``; returns the files written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [out / "result.json", out / "result.npz"]
    files[0].write_text(json.dumps(result.to_json(), indent=2))
    np.savez(
        files[1],
        params=result.params,
        param_names=np.array(PARAM_NAMES),
        trial_params=result.trial_params,
        trial_costs=result.trial_costs,
        history=result.history,
        stderr=np.array([result.stderr[n] for n in PARAM_NAMES]),
    )
    files.append(_verification(result, train, "zero", out / "verification_train.png", f"{result.method}: training flight"))
    if validate is not None:
        files.append(
            _verification(result, validate, "estimate", out / "verification_validate.png",
                          f"{result.method}: validation flight (initial state estimated)")
        )
    if result.history.size:
        curves = {f"trial {k}": h for k, h in enumerate(result.history)}
        files.append(plot_convergence(curves, out / "convergence.png", f"{result.method} convergence"))
    return files
