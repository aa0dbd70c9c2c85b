"""Identification benchmark: recovery of known truths on synthetic piloted flights, and the real TREX 550 flights.

``synthetic``: for each truth (the paper's Table 2; Mettler's Yamaha R-50 converted to SI) and sensor-noise level,
a training flight (80 s, the embedded default's excitation: 3-2-1-1s then sweeps on every axis, seed 1) and a
validation flight of another style and seed (60 s of 3-2-1-1s, unit 0.4 s, a pilot who holds the attitude more
tightly). Every method identifies on the training flight in the box a user sets for the class (the authors' TREX
box for Table 2; the TREX box widened to hold half to twice each Table 2 and R-50 parameter for the R-50,
:data:`jaxheli.benchmark.blind.BOX`). Reported per run: validation fit % per channel next to the truth model's own on
the same flight (initial state estimated for both), the largest shortfall, and the share of identifiable
parameters within 3 Cramer-Rao standard errors of the truth.

``real``: trains on flight A (``Data_graphready.mat``, prepared as ``benchmarks/paper_comparison.py`` does: 50
samples trimmed at each end, the consistency findings corrected, 3 Hz low-pass) and on its first 60 %; validates on
flight C (``ppr_data.mat``, low-passed alike) and on A's last 40 % (held out for the 60 % model, not for the A model,
and marked so). A's whole armed session (``tested.mat``) holds no more flight: it is airborne from about row 4000 to
row 12500 (``../shared/data/README.md``), the rows ``Data_graphready.mat`` holds (4136-12725); the rest is arming,
spool-up and landing on the ground, which the hover model does not describe (its first 60 % holds about 40 s of
it). Pearson, fit % and TIC per channel (p, q, phi, theta) over 5-s runs each from its least-squares start with a per-channel bias
(:func:`jaxheli.verify.verify`, issue 35's measure) and over one run (initial state estimated, and from rest), next to
the paper's Table 2 model scored by the same code. Every ``+polish`` method runs once per ``--cv-windows`` value:
with the polish's last run length and stopping round chosen by leave-one-window-out cross-validation over that many
windows of the training record (:mod:`jaxheli.optim.cross_validate`), and (0) with its full schedule. ``--train``
chooses the training records among all four: a validation record trained on and scored on itself gives the method's
in-sample ceiling there (what no model trained elsewhere is expected to exceed with the same objective).
``--recipes`` runs each method in each recipe (issue 66): ``default`` (the authors' box, :data:`jaxheli.model.LOWER`
/ ``UPPER``, what ``jaxheli identify`` does) or a ``+``-join of ``physical`` (the physical box,
:data:`jaxheli.model.WIDE_LOWER` / ``WIDE_UPPER``: ``jaxheli identify --box wide``), ``structure`` (model-structure
determination after the fit: ``--structure``), ``prior`` (a Gaussian prior toward ``--prior``, default Table 2,
in the local fits: ``--prior table2``), ``full`` (every record fitted at its own step, ``--fit-dt full``, where the
default fits a low-passed one at its bandwidth step) and ``zoh`` (the sticks held zero-order between samples, in the
fit and in its scores, ``--hold zoh``, where the default holds a low-passed record's first-order); ``full+zoh`` is
the default before 2026-12-03. Every row is labelled held out or in-sample
(Table 2's: unknown, its training flight is not recorded), with the seconds of its fit and the model's unstable modes (eigenvalues of the
continuous ``A`` with positive real part, :func:`jaxheli.modes.modes`).

Usage::

    python benchmarks/identification.py synthetic [--methods iwo+freq+polish iwo+polish pem] [--noises 1 3] [--iterations 100]
    python benchmarks/identification.py real [--methods iwo+freq+polish iwo+polish pem] [--iterations 1000] [--cv-windows 4 0]
    python benchmarks/identification.py real --methods iwo+freq+polish --cv-windows 0 --train C "A, last 40 %"
    python benchmarks/identification.py real --methods iwo+freq+polish --cv-windows 0 --iterations 1000 \
        --recipes default physical structure physical+structure prior
    python benchmarks/identification.py real --methods iwo+freq+polish --cv-windows 0 --iterations 1000 \
        --recipes default physical --seeds 0 1 2 --trials 1

``--seeds`` runs every fit once per seed (``--trials`` trials each, the best kept); with several, ``tables.md`` adds
each held-out score's median and range over the seeds, the spread a recipe's single run stands in for.

Writes ``rows.json``, ``record.json`` (the rows with the run's settings, for ``docs/gen_benchmarks.py record``) and
``tables.md`` under ``--out`` (default ``results/identification/<part>``), after every run.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import jax
import numpy as np

import jaxheli
from jaxheli.data.preprocess import split
from jaxheli.benchmark.blind import BOX
from jaxheli.bounds import named_box
from jaxheli.gap.prepare import prepare
from jaxheli.identify import identify, validation_block
from jaxheli.io.paths import data_file
from jaxheli.model import LOWER, R50_SI, TABLE2, UPPER
from jaxheli.modes import modes
from jaxheli.stages import METHODS, PRIOR_SD, uses
from jaxheli.spectra import estimate_frequency_response
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import DEFAULT_EXCITATION, Pilot, piloted_flight
from jaxheli.verify import verify

TRUTHS = {"table2": (TABLE2, (LOWER, UPPER)), "r50": (R50_SI, BOX)}
"""Truth models and the identification box of each."""

SYNTH_CHANNELS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
REAL_CHANNELS = ("p", "q", "phi", "theta")
REAL_LOWPASS_HZ = 3.0
RUN_S = 5.0
"""Verification run length, s (issue 35's measure: each run from its least-squares start with a per-channel bias)."""


RECIPE_PARTS = ("physical", "structure", "prior", "full", "zoh")
"""What a recipe (``--recipes``) may join with ``+``; ``default`` is none of them."""


def _search(method: str, iterations: int) -> dict:
    """The population search's options where ``method`` has one (identify refuses them elsewhere)."""
    return {"iterations": iterations, "progress": False} if uses(method, "iterations") else {}


def synthetic_flights(theta: np.ndarray, noise: float) -> tuple[jaxheli.FlightData, jaxheli.FlightData]:
    """Training and validation flights of one truth: different excitation style, pilot and seed."""
    train = piloted_flight(theta, duration=80.0, dt=0.01, excitation=DEFAULT_EXCITATION, seed=1, noise=noise)
    validate = piloted_flight(theta, duration=60.0, dt=0.01, excitation=Excitation("3211", unit=0.4), seed=2,
                              noise=noise, pilot=Pilot(max_stick=0.3))
    return train, validate


def _synthetic(args: argparse.Namespace, out: Path) -> list[dict]:
    rows = []
    for name, (theta, (lower, upper)) in TRUTHS.items():
        for noise in args.noises:
            train, validate = synthetic_flights(theta, noise)
            for method, seed in [(m, s) for m in args.methods for s in args.seeds]:
                t0 = time.perf_counter()
                res = identify(train, method=method, validate=validate, seed=seed, trials=args.trials, lower=lower,
                               upper=upper, truth=theta, **_search(method, args.iterations))
                fit = res.validate["fit_percent"]
                truth_fit = res.truth["validate"]["fit_percent"]
                rows.append({
                    "truth": name, "noise": noise, "method": method, "seed": seed, "trials": args.trials,
                    "seconds": time.perf_counter() - t0,
                    "fit_percent": fit, "truth_fit_percent": truth_fit,
                    "shortfall": max(truth_fit[c] - fit[c] for c in fit),
                    "pearson": res.validate["pearson"], "tic": res.validate["tic"],
                    "cramer_rao_within": res.truth["cramer_rao"]["fraction"],
                    "identifiable": len(res.truth["cramer_rao"]["identifiable"]),
                })
                _write(out, rows, _synthetic_table(rows, args))
                print(f"{name} noise {noise} {method} seed {seed}: {rows[-1]['seconds']:.0f} s, shortfall "
                      f"{rows[-1]['shortfall']:.2f} points, CR {rows[-1]['cramer_rao_within']:.2f}", flush=True)
    return rows


def _synthetic_table(rows: list[dict], args: argparse.Namespace) -> str:
    lines = [f"# Synthetic recovery ({_machine()}; {args.iterations} generations, {_seeds(args)})", "",
             "Validation fit % per channel, model / truth (initial state estimated); CR: share of identifiable "
             "parameters within 3 Cramer-Rao standard errors of the truth.", "",
             "| truth | noise | method | seed | s | " + " | ".join(SYNTH_CHANNELS) + " | worst shortfall | CR |",
             "|---" * (len(SYNTH_CHANNELS) + 7) + "|"]
    for r in rows:
        cells = " | ".join(f"{r['fit_percent'][c]:.1f} / {r['truth_fit_percent'][c]:.1f}" for c in SYNTH_CHANNELS)
        lines.append(f"| {r['truth']} | {r['noise']:g} | {r['method']} | {r['seed']} | {r['seconds']:.0f} | {cells} | "
                     f"{r['shortfall']:.2f} | {r['cramer_rao_within']:.2f} of {r['identifiable']} |")
    return "\n".join(lines) + "\n"


def real_flights() -> tuple[dict[str, jaxheli.FlightData], dict[str, jaxheli.FlightData]]:
    """Training records (A's airborne segment; its first 60 %) and validation records (flight C; A's last 40 %),
    prepared alike."""
    steps = {"trim_samples": 50, "correct_data": True, "lowpass_hz": REAL_LOWPASS_HZ}
    segment = prepare(jaxheli.load(data_file("trex550/Data_graphready.mat")), **steps)
    first, last = split(segment, 0.6)
    flight_c = prepare(jaxheli.load(data_file("trex550/ppr_data.mat")), lowpass_hz=REAL_LOWPASS_HZ)
    return {"A": segment, "A, first 60 %": first}, {"C": flight_c, "A, last 40 %": last}


def _excitation(records: dict[str, jaxheli.FlightData]) -> str:
    """Each record's stick rms and the mean partial coherence (:func:`jaxheli.spectra.estimate_frequency_response`,
    its default Welch segment) over 0.3-3 Hz of the pairs that carry the roll and pitch responses."""
    pairs = (("lat", "p"), ("lat", "phi"), ("lon", "q"), ("lon", "theta"))
    outs = tuple(dict.fromkeys(o for _, o in pairs))
    lines = ["## Excitation: stick rms (normalised sticks) and mean partial coherence over 0.3-3 Hz", "",
             "| record | s | rms lat | rms lon | rms ped | rms col | " + " | ".join(f"{i}->{o}" for i, o in pairs)
             + " |", "|---" * (6 + len(pairs)) + "|"]
    for label, flight in records.items():
        fr = estimate_frequency_response(flight.inputs, flight.select(outs).outputs, flight.dt)
        band = (np.asarray(fr.freq) >= 0.3) & (np.asarray(fr.freq) <= 3.0)
        coh = [float(np.mean(np.asarray(fr.coherence)[band, outs.index(o), flight.input_names.index(i)]))
               for i, o in pairs]
        rms = np.std(flight.inputs, axis=0)
        lines.append(f"| {label} | {flight.duration:.1f} | " + " | ".join(f"{v:.3f}" for v in rms) + " | "
                     + " | ".join(f"{c:.2f}" for c in coh) + " |")
    return "\n".join(lines) + "\n"


def recipe_options(recipe: str, prior: str | None, prior_sd: float) -> dict:
    """identify's options of ``recipe`` (``default`` or a ``+``-join of :data:`RECIPE_PARTS`): the box, the
    structure determination and the prior (``prior``, default Table 2, sd ``prior_sd`` % of each value)."""
    parts = [] if recipe == "default" else recipe.split("+")
    if recipe != "default" and (not set(parts) <= set(RECIPE_PARTS) or len(set(parts)) < len(parts)):
        raise ValueError(f"recipe {recipe!r}: 'default' or a '+'-join of {RECIPE_PARTS}")
    box = named_box("wide" if "physical" in parts else "authors")
    options = {"lower": np.asarray(box.lower, np.float64), "upper": np.asarray(box.upper, np.float64)}
    if "structure" in parts:
        options["structure"] = True
    if "prior" in parts or prior:
        options.update(prior=prior or "table2", prior_sd=prior_sd)
    if "full" in parts:
        options["fit_dt"] = "full"
    if "zoh" in parts:
        options["hold"] = "zoh"
    return options


def unstable_modes(params: np.ndarray) -> list[dict]:
    """The model's unstable modes (eigenvalues of the continuous ``A`` with positive real part, one per complex
    pair): eigenvalue (1/s), name and time to double (s)."""
    return [{"eigenvalue": [m.eigenvalue.real, m.eigenvalue.imag], "name": m.name,
             "time_to_double_s": m.time_to_double} for m in modes(params) if m.time_to_double is not None]


def _sample(train_label: str, label: str) -> str:
    """``held out`` unless the validation record ``label`` is (part of) the training record ``train_label``."""
    inside = label == train_label or (train_label == "A" and label.startswith("A,"))
    return "in-sample" if inside else "held out"


def _real(args: argparse.Namespace, out: Path) -> list[dict]:
    recipes = {recipe: recipe_options(recipe, args.prior, args.prior_sd) for recipe in args.recipes}
    trains, validations = real_flights()
    records = {**trains, **validations}
    excitation = _excitation(records)
    trains = {label: records[label] for label in args.train or trains}
    rows = []
    for label, validation in validations.items():
        rows.append({"train": "-", "recipe": "-", "method": "paper Table 2", "validate": label, "seconds": 0.0,
                     "held_out": True, "sample": "unknown", "unstable_modes": unstable_modes(TABLE2),
                     **_real_scores(TABLE2, validation)})
    for train_label, train in trains.items():
        for recipe, options in recipes.items():
            for method, seed in [(m, s) for m in args.methods for s in args.seeds]:
                for cv in args.cv_windows if method.endswith("+polish") else [0]:
                    rows += _real_fit(args, train_label, train, validations, recipe, method, cv, options, seed)
                    _write(out, rows, _real_table(rows, args) + "\n" + _spread_table(rows) + "\n" + excitation, args)
    return rows


def _real_fit(args: argparse.Namespace, train_label: str, train: jaxheli.FlightData,
              validations: dict[str, jaxheli.FlightData], recipe: str, method: str, cv: int, options: dict,
              seed: int) -> list[dict]:
    """One fit (``method`` in ``recipe``, ``cv`` windows of cross-validation or none, ``seed`` and ``args.trials``
    trials) on the training record, timed, scored on every validation record."""
    t0 = time.perf_counter()
    res = identify(train, method=method, seed=seed, trials=args.trials, cv_windows=cv or None, **options,
                   **_search(method, args.iterations))
    seconds = time.perf_counter() - t0
    chosen = (res.polish or {}).get("cross_validation")
    name = method if not cv else f"{method}, cv {cv}: {chosen['final_s']:.3g} s x {chosen['rounds']}"
    name += f", prior {options['prior']} {options['prior_sd']:g} %" if "prior" in options else ""
    found = {"train": train_label, "recipe": recipe, "method": name, "seed": seed, "trials": args.trials,
             "seconds": seconds, "iterations":
             args.iterations if uses(method, "iterations") else None, "cross_validation": chosen,
             "fixed": sorted(res.fixed or {}), "unstable_modes": unstable_modes(res.params)}
    print(f"{train_label} {recipe} {name} seed {seed}: {seconds:.0f} s", flush=True)
    samples = {label: _sample(train_label, label) for label in validations}
    return [{**found, "validate": label, "held_out": samples[label] == "held out", "sample": samples[label],
             **_real_scores(res.params, validation, res.settings["hold"])}
            for label, validation in validations.items()]


def _real_scores(params: np.ndarray, flight: jaxheli.FlightData, hold: str = "zoh") -> dict:
    block = validation_block(params, flight, REAL_CHANNELS, hold=hold)
    runs = verify(params, flight, run_length=RUN_S, hold=hold).pooled
    return {"estimated": _metrics(block), "zero": _metrics(block["zero_initial_state"]), "runs": _metrics(runs)}


def _metrics(block: dict) -> dict:
    return {key: block[key] for key in ("pearson", "fit_percent", "tic")}


def _real_table(rows: list[dict], args: argparse.Namespace) -> str:
    lines = [f"# Real flights ({_machine()}; {args.iterations} generations, {_seeds(args)})", "",
             "`*`: the validation record overlaps the training record (in-sample). Channels p q phi theta. "
             "Unstable modes: rows.json and the Benchmarks page (docs/gen_benchmarks.py's recipes).", ""]
    cols = (("pearson", "r", ".3f"), ("fit_percent", "fit", ".1f"), ("tic", "TIC", ".3f"))
    for title, key in (
            (f"{RUN_S:g}-s runs, each from its least-squares start with a per-channel bias (`jaxheli verify`)", "runs"),
            ("One run over the window: Pearson from rest | fit % and TIC, initial state estimated", None)):
        lines += [f"## {title}", "", "| train | recipe | method | seed | validate | sample | s | " + " | ".join(
            f"{short} {c}" for _, short, _ in cols for c in REAL_CHANNELS) + " |",
            "|---" * (7 + 3 * len(REAL_CHANNELS)) + "|"]
        for r in rows:
            blocks = [r[key]] * 3 if key else [r["zero"], r["estimated"], r["estimated"]]
            cells = [f"{block[metric][c]:{fmt}}" for block, (metric, _, fmt) in zip(blocks, cols) for c in REAL_CHANNELS]
            mark = "" if r["held_out"] else " *"
            lines.append(f"| {r['train']} | {r.get('recipe', '-')} | {r['method']} | {r.get('seed', '-')} | "
                         f"{r['validate']}{mark} | "
                         f"{r.get('sample', '-')} | {r['seconds']:.0f} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def _spread_table(rows: list[dict]) -> str:
    """Over the seeds of each training record, recipe, method and validation record: the median and the range of
    Pearson and fit % per channel (5-s runs); empty when every such fit ran with one seed."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["recipe"] != "-":
            groups.setdefault((r["train"], r["recipe"], r["method"], r["validate"]), []).append(r)
    if all(len(g) < 2 for g in groups.values()):
        return ""
    lines = ["## Over seeds: median [lowest, highest], 5-s runs", "",
             "| train | recipe | method | validate | sample | seeds | "
             + " | ".join(f"{short} {c}" for short in ("r", "fit") for c in REAL_CHANNELS) + " |",
             "|---" * (6 + 2 * len(REAL_CHANNELS)) + "|"]
    for (train, recipe, method, validate), group in groups.items():
        cells = []
        for metric, fmt in (("pearson", ".3f"), ("fit_percent", ".1f")):
            for c in REAL_CHANNELS:
                values = [r["runs"][metric][c] for r in group]
                cells.append(f"{np.median(values):{fmt}} [{min(values):{fmt}}, {max(values):{fmt}}]")
        lines.append(f"| {train} | {recipe} | {method} | {validate} | {group[0]['sample']} | {len(group)} | "
                     + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _seeds(args: argparse.Namespace) -> str:
    """The seeds and trials of a run, for a table's title."""
    return f"seeds {', '.join(map(str, args.seeds))}, {args.trials} trial(s) each"


def _machine() -> str:
    return f"{platform.machine()}, {jax.device_count()} {jax.default_backend()} device(s), jax {jax.__version__}"


def _write(out: Path, rows: list[dict], table: str, args: argparse.Namespace | None = None) -> None:
    (out / "rows.json").write_text(json.dumps(rows, indent=1, default=float))
    if args is not None:
        settings = {k: v for k, v in vars(args).items() if k != "out"}
        record = {"argv": sys.argv[1:], "settings": settings, "machine": _machine(), "rows": rows}
        (out / "record.json").write_text(json.dumps(record, indent=1, default=float))
    (out / "tables.md").write_text(table)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("part", choices=("synthetic", "real"))
    parser.add_argument("--methods", nargs="+", default=["iwo+freq+polish", "iwo+polish", "pem"], choices=METHODS)
    parser.add_argument("--noises", nargs="+", type=float, default=[1.0, 3.0],
                        help="sensor-noise levels, multiples of the default (synthetic)")
    parser.add_argument("--iterations", type=int, default=100, help="IWO / GA generations")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0],
                        help="random seeds, one fit of each method per seed (default 0); real: the tables add each "
                             "score's median and range over the seeds")
    parser.add_argument("--trials", type=int, default=1, help="identify's trials per fit, the best kept (default 1)")
    parser.add_argument("--cv-windows", nargs="+", type=int, default=[4, 0],
                        help="real: windows of the polish's leave-one-window-out cross-validation, one run per value "
                             "(0: the polish's full schedule; default 4 0, both side by side)")
    parser.add_argument("--prior", default=None, metavar="MODEL",
                        help="real: a prior model for PEM and the polish (as `jaxheli identify --prior`, e.g. table2)")
    parser.add_argument("--prior-sd", type=float, default=PRIOR_SD, metavar="PCT",
                        help="the prior's sd, %% of each value (default: identify's)")
    parser.add_argument("--recipes", nargs="+", default=["default"], metavar="RECIPE",
                        help="real: recipes, each 'default' (the authors' box) or a '+'-join of "
                             f"{', '.join(RECIPE_PARTS)} (e.g. physical+structure; default: default)")
    parser.add_argument("--train", nargs="+", default=None, metavar="RECORD",
                        choices=("A", "A, first 60 %", "C", "A, last 40 %"),
                        help="real: the records to train on (default: A and its first 60 %%); a validation record "
                             "trained on and scored on itself is the method's in-sample ceiling there, marked *")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    out = Path(args.out or f"results/identification/{args.part}")
    out.mkdir(parents=True, exist_ok=True)
    rows = _synthetic(args, out) if args.part == "synthetic" else _real(args, out)
    print((out / "tables.md").read_text())
    print(f"{len(rows)} rows in {out}")


if __name__ == "__main__":
    main()
