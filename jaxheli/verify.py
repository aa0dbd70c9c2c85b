"""Time-domain verification of an identified model on a flight it was not fitted to (Tischler and Remple, *Aircraft
and Rotorcraft System Identification*, ch. 14).

The flight is cut into runs of a fixed length (5 s by default; 10 s, or the whole window). Each run is simulated
from its own least-squares initial state with a constant output bias per channel fitted beside it
(:func:`jaxheli.evaluate.biased_start_outputs`), so neither the attitude the run starts from nor the sensors'
offsets are charged to the model; what is left is the model's response to the run's sticks. Scores per run and
channel, and over all runs pooled (the runs' samples concatenated):

- TIC, Theil's inequality coefficient (:func:`jaxheli.cost.tic`; guideline <= 0.25-0.3);
- ``J_rms = sqrt(1/(n n_o) sum_i sum_k e_ik' W e_ik)`` over the ``n`` samples and ``n_o`` channels, with
  ``W = diag(1 / s_k^2)``, ``s_k`` the standard deviation of measured channel ``k`` over the whole window (one
  weight for every run; per channel, ``J_rms`` is its RMSE over ``s_k``). With this normalisation ``J_rms = 1`` is
  an error as large as the channel's own spread; the book's guideline is ``J_rms <= 1-2``;
- Pearson's rho and the normalised fit % (:mod:`jaxheli.cost`).

Overall: ``J_rms`` by its formula over every channel; TIC, Pearson and fit % the mean over the channels. A channel
whose own slow mode is nearly constant over a run (Table 2's heave root, +0.046 1/s, on w) splits its offset between
the start and the bias almost freely: their sum, the simulated run and its scores are determined, each alone is not. The
model's modes (:mod:`jaxheli.modes`) say how long a run may be: a run longer than the doubling time of an unstable
mode that shows in the scored channels measures the start's error grown, not the model.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ._progress import stage
from ._types import Float
from .cost import metrics
from .data.flight import FlightData, constant_outputs, default_outputs
from .evaluate import biased_start_outputs, recorded_hold, resolve_params
from .model import G_SI
from .modes import Mode, fastest_doubling, modes
from .plots import plot_time_domain
from .problem import make_problem
from .sim.discretize import Hold

RUN_LENGTHS: tuple[float | None, ...] = (5.0, 10.0, None)
"""Run lengths, s, of the book's practice (``None``: the whole window as one run)."""
TIC_GUIDE = 0.3
"""Upper end of the TIC guideline (0.25-0.3)."""
J_RMS_GUIDE = 2.0
"""Upper end of the ``J_rms`` guideline (1-2)."""
METRICS: tuple[str, ...] = ("tic", "j_rms", "pearson", "fit_percent", "rmse")
"""Scores of every run and channel (``rmse`` in the channel's units)."""


@dataclasses.dataclass(frozen=True)
class Run:
    """One run: its span on the record's time axis (s), start (``x0[13]``, ``bias[k]``), samples and scores.

    ``scores[metric][channel]`` for :data:`METRICS`, with ``"overall"`` beside the channels (not for ``rmse``).
    """

    start_s: float
    end_s: float
    x0: Float[np.ndarray, "13"]
    bias: Float[np.ndarray, "k"]
    time: Float[np.ndarray, "n"]
    measured: Float[np.ndarray, "n k"]
    simulated: Float[np.ndarray, "n k"]
    scores: dict[str, dict[str, float]]


@dataclasses.dataclass(frozen=True)
class Verification:
    """A model verified on one flight with one run length.

    Attributes:
        source: the flight's source; ``channels`` the scored channels; ``run_length`` the runs' length, s
            (``None``: the whole window); ``spread`` each channel's standard deviation over the window (``W``).
        runs: the runs, in time order; ``pooled`` their scores over all samples together (as ``Run.scores``).
        modes: the model's modes; ``notes`` what the reader must know (a mode faster than the runs, channels
            left out, samples left over).
    """

    source: str
    channels: tuple[str, ...]
    run_length: float | None
    spread: dict[str, float]
    runs: tuple[Run, ...]
    pooled: dict[str, dict[str, float]]
    modes: tuple[Mode, ...]
    notes: tuple[str, ...]

    def to_json(self) -> dict[str, object]:
        """JSON-ready content: settings, pooled scores, each run's span, start and scores, notes."""
        return {
            "source": self.source,
            "channels": list(self.channels),
            "run_length_s": self.run_length,
            "weights": {c: 1.0 / s**2 for c, s in self.spread.items()},
            "weighting": "W = 1/std^2 of each measured channel over the window",
            "pooled": self.pooled,
            "runs": [{"start_s": r.start_s, "end_s": r.end_s, "x0": r.x0.tolist(),
                      "bias": dict(zip(self.channels, map(float, r.bias))), "scores": r.scores} for r in self.runs],
            "notes": list(self.notes),
        }


def verify(
    params: str | Path | np.ndarray | dict, flight: FlightData, *, run_length: float | None = 5.0,
    outputs: tuple[str, ...] | None = None, hold: Hold | None = None, g: float = G_SI,
) -> Verification:
    """Verify ``params`` (anything :func:`jaxheli.evaluate.resolve_params` takes) on ``flight`` in runs of
    ``run_length`` s (``None``: one run over the whole window; a window shorter than a run is one run).

    ``outputs``: the scored channels (default :func:`~jaxheli.data.flight.default_outputs`); ``hold``, ``g``: the
    simulation's (``hold`` by default the one a result was fitted with, :func:`~jaxheli.evaluate.recorded_hold`,
    else zero-order). Samples left after the last whole run are left out (said in ``notes``).
    """
    theta = resolve_params(params)
    hold = hold or recorded_hold(params) or "zoh"
    spans, notes = _spans(flight, run_length)
    asked = tuple(outputs or default_outputs(flight))
    flat = sorted({c for a, b in spans for c in constant_outputs(_cut(flight, a, b).select(asked))}, key=asked.index)
    chans = tuple(c for c in asked if c not in flat)
    if not chans:
        raise ValueError(f"{flight.source}: every channel of {asked} is constant over some run; nothing to verify")
    if flat:
        notes.append(f"channel(s) {', '.join(flat)} constant over some run: left out")
    spread = flight.select(chans).outputs.std(axis=0)
    with stage(f"verification on {flight.source}: {len(spans)} run(s)"):
        runs = tuple(_run(theta, _cut(flight, a, b), chans, spread, hold, g) for a, b in spans)
    pooled = _scores(np.concatenate([r.simulated for r in runs]), np.concatenate([r.measured for r in runs]),
                     chans, spread)
    found = modes(theta, g)
    length = (spans[0][1] - spans[0][0] - 1) * flight.dt
    notes.extend(_growth_note(fastest_doubling(found, chans), length, whole=spans == [(0, flight.n_samples)]))
    return Verification(flight.source, chans, run_length, dict(zip(chans, map(float, spread))), runs, pooled, found,
                        tuple(notes))


def _spans(flight: FlightData, run_length: float | None) -> tuple[list[tuple[int, int]], list[str]]:
    """Sample ranges ``[a, b)`` of the runs, and a note on samples left over."""
    if run_length is not None and not run_length > 0:
        raise ValueError(f"run length must be positive, got {run_length} s")
    n = flight.n_samples
    size = n if run_length is None else int(round(run_length / flight.dt)) + 1
    if size >= n:
        if run_length is None:
            return [(0, n)], []
        return [(0, n)], [f"window ({flight.duration:.3g} s) no longer than a {run_length:g}-s run: one run over it"]
    count = (n - 1) // (size - 1)
    spans = [(j * (size - 1), j * (size - 1) + size) for j in range(count)]
    left = n - spans[-1][1]
    return spans, [f"last {left * flight.dt:.3g} s ({left} samples) shorter than a run: left out"] if left else []


def _cut(flight: FlightData, a: int, b: int) -> FlightData:
    return flight.replace(time=flight.time[a:b], inputs=flight.inputs[a:b], outputs=flight.outputs[a:b])


def _run(theta: np.ndarray, part: FlightData, chans: tuple[str, ...], spread: np.ndarray, hold: Hold, g: float) -> Run:
    """One run simulated from its least-squares start with output bias, and its scores."""
    start, y = biased_start_outputs(make_problem(part, outputs=chans, hold=hold, g=g), theta)
    meas = part.select(chans).outputs
    return Run(float(part.time[0]), float(part.time[-1]), start.x0, start.bias, part.time, meas, y,
               _scores(y, meas, chans, spread))


def _scores(
    sim: np.ndarray, meas: np.ndarray, chans: tuple[str, ...], spread: np.ndarray
) -> dict[str, dict[str, float]]:
    """:data:`METRICS` per channel and overall (module docstring)."""
    base = metrics(sim, meas, chans)
    out = {key: dict(base[key]) for key in ("tic", "pearson", "fit_percent", "rmse")}
    rmse = np.array([out["rmse"][c] for c in chans])
    j = rmse / spread
    out["j_rms"] = dict(zip(chans, map(float, j)))
    out["j_rms"]["overall"] = float(np.sqrt(np.mean(j**2)))
    for key in ("tic", "pearson", "fit_percent"):
        out[key]["overall"] = float(np.mean([out[key][c] for c in chans]))
    return {key: out[key] for key in METRICS}


def _growth_note(mode: Mode | None, length: float, whole: bool) -> list[str]:
    """A note when the fastest unstable mode seen in the channels doubles within a run."""
    if mode is None or mode.time_to_double >= length:
        return []
    lam, doubling = mode.eigenvalue, mode.time_to_double
    text = (f"the model's {mode.name} mode ({lam.real:+.3g}{f' +- {lam.imag:.3g}j' if mode.oscillatory else ''} 1/s) "
            f"doubles every {doubling:.3g} s, within a {length:.3g}-s run "
            f"({np.exp2(length / doubling):.3g}-fold growth over it)")
    if whole:
        text += ": a whole-window comparison (from rest, or from one fitted start) is meaningless; use short runs"
    return [text]


def save_verification(found: Sequence[Verification], model: str, out_dir: str | Path) -> list[Path]:
    """Write ``verification.json`` (the model, its modes and every verification), ``verification.csv`` (one row
    per flight, run length, run and channel; run ``pooled`` for all runs together) and a PNG of every run (flight
    against model) under ``out_dir``; returns the files written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [out / "verification.json", out / "verification.csv"]
    content = {"model": model, "modes": [m.to_json() for m in found[0].modes] if found else [],
               "verifications": [v.to_json() for v in found]}
    files[0].write_text(json.dumps(content, indent=2))
    with files[1].open("w", newline="") as handle:
        rows = csv.writer(handle)
        rows.writerow(["source", "run_length_s", "run", "start_s", "end_s", "channel", *METRICS])
        for v in found:
            length = "whole" if v.run_length is None else f"{v.run_length:g}"
            blocks = [(str(k), f"{r.start_s:.6g}", f"{r.end_s:.6g}", r.scores) for k, r in enumerate(v.runs)]
            blocks.append(("pooled", f"{v.runs[0].start_s:.6g}", f"{v.runs[-1].end_s:.6g}", v.pooled))
            for run, a, b, scores in blocks:
                for c in (*v.channels, "overall"):
                    rows.writerow([v.source, length, run, a, b, c,
                                   *(f"{scores[m][c]:.6g}" if c in scores[m] else "" for m in METRICS)])
    for k, v in enumerate(found):
        length = "whole" if v.run_length is None else f"{v.run_length:g}s"
        for j, r in enumerate(v.runs):
            overall = {m: r.scores[m]["overall"] for m in ("tic", "j_rms")}
            title = (f"{model} on {Path(v.source).name}, run {j + 1} of {len(v.runs)} ({r.start_s:.4g}-{r.end_s:.4g} "
                     f"s): TIC {overall['tic']:.2f}, J_rms {overall['j_rms']:.2f}")
            files.append(plot_time_domain(r.time, r.measured, {"model": r.simulated}, v.channels,
                                          out / f"run_{k + 1}_{length}_{j + 1:03d}.png", title))
    return files
