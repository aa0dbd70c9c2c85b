"""``jaxheli identify | evaluate | synth``: fit the 40 parameters, score a model on a flight, write a flight."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from ..cost import SEARCH_COSTS
from ..flights import DEFAULT_DATA
from ..bounds import BOXES, named_box
from ..optim.frequency_fit import MAX_STEPS as FREQ_STEPS, STARTS as FREQ_STARTS
from ..optim.polish import POLISH_OBJECTIVES
from ..stages import METHODS, PRIOR_SD, used_by, uses
from ._options import (add_data_option, add_flight_option, add_load_options, add_quiet_option, add_sim_options,
                       fit_step, outputs, read_flight, sim_options)
from .verify import print_modes, print_verification


_KEYWORDS = {"iterations": "--iterations", "resume": "--resume", "chunk": "--checkpoint-every",
             "search_precision": "--search-precision", "cost": "--cost", "polish_objective": "--polish-objective",
             "polish_steps": "--polish-steps", "polish_rounds": "--polish-rounds", "cv_windows": "--cv-windows",
             "structure": "--structure", "prior": "--prior", "prior_sd": "--prior-sd"}
"""identify's option keywords and the options of ``jaxheli identify`` that give them (passed only when given)."""

_FREQ_OPTIONS = {"starts": "--freq-starts", "screen": "--freq-screen", "max_steps": "--freq-steps",
                 "band": "--freq-band"}
"""The frequency fit's keywords (identify's ``freq_options``) and the options that give them."""

_FREQ_DEFAULTS = {"starts": FREQ_STARTS, "screen": 2000, "max_steps": FREQ_STEPS, "band": None}
"""What the frequency fit's options are where not given."""


def add_identify_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``identify`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser("identify", help="fit the 40 parameters to a flight (IWO, GA, PEM, IWO + polish, "
                                               "frequency domain)")
    run = p.add_argument_group("what to fit, and where the results go")
    run.add_argument("--method", choices=METHODS, default="iwo+freq+polish",
                     help="engine (default iwo+freq+polish: IWO, its best starting the frequency fit, then the "
                          "polish); freq: frequency responses fitted on Tischler's cost J (CIFER); freq+polish: "
                          "then the time-domain polish")
    add_data_option(run, f"the training flight(s), several fitted at once, each its own initial state, costs "
                         f"added (default: {DEFAULT_DATA})", aliases=("--train",), several=True)
    add_flight_option(run, "--validate", "the validation flight (optional)")
    run.add_argument("--out", default="jaxheli-result", help="output folder (result.json, result.npz, PNGs)")
    run.add_argument("--trials", type=int, default=1, help="independent trials for 95%% intervals (the paper: 10)")
    run.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    add_quiet_option(run)

    search = p.add_argument_group(f"the search (methods {used_by('iterations')})")
    search.add_argument("--iterations", type=int, default=None,
                        help="IWO / GA generations (default 1000, the paper)")
    search.add_argument("--cost", choices=SEARCH_COSTS, default=None,
                        help="what IWO / GA minimise: pearson (default, the paper's Eq. 7) or output-error")
    search.add_argument("--search-precision", choices=("float32", "float64"), default=None,
                        help="arithmetic of the IWO / GA population scoring (default float32: fast, checked "
                             "against float64)")
    search.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.eqx")
    search.add_argument("--checkpoint-every", type=int, default=None, metavar="N",
                        help="write OUT/checkpoint.eqx every N generations (default 50); a resume continues from it")

    polish = p.add_argument_group(f"the polish, Levenberg-Marquardt after the search (methods "
                                  f"{used_by('polish_steps')})")
    polish.add_argument("--polish-objective", choices=POLISH_OBJECTIVES, default=None,
                        help="what the polish minimises: output-error (default: normalised output errors, every "
                             "run from its least-squares state, runs shortened where the model is unstable), "
                             "pearson (with --cost pearson: the paper's pure pipeline) or pem")
    polish.add_argument("--polish-steps", type=int, default=None,
                        help="Levenberg-Marquardt steps per polish round (default 100)")
    polish.add_argument("--polish-rounds", type=int, default=None,
                        help="output-error polish: at most this many rounds, the first on 5 s then 20 s runs "
                             "(default 4)")
    polish.add_argument("--cv-windows", type=int, default=None, metavar="W",
                        help="output-error polish on one flight: choose its last run length (5 s, 20 s, a window's "
                             "length) and stopping round by leave-one-window-out cross-validation over W windows "
                             "of the flight (W fits of each run length, each on W - 1 windows; default 0: the full "
                             "schedule)")

    model = p.add_argument_group("the model: box, structure, prior, fit step")
    model.add_argument("--box", choices=BOXES, default="authors",
                       help="search box: authors (default, their config_iwo.m; Lw, Mw, Nw, Yped, Mcol pinned at 0) "
                            "or wide (the physical ranges, jaxheli.model.WIDE_LOWER/UPPER, every parameter free)")
    model.add_argument("--structure", action="store_true",
                       help="model-structure determination after the fit: fix the parameters the flight cannot "
                            "determine (unresolved, relative Cramer-Rao bound > 20 %%, or the worse of a pair "
                            "correlated > 0.95) to the prior, 0 or the nearest bound and re-fit (methods pem and "
                            "*+polish)")
    model.add_argument("--prior", default=None, metavar="MODEL",
                       help="a prior model (result.json or table2): a Gaussian prior in the local fits (PEM, "
                            "polish) and the values --structure fixes parameters at")
    model.add_argument("--prior-sd", type=float, default=None, metavar="PCT",
                       help=f"the prior's standard deviation, %% of each value, floored at 1 %% of the parameter's "
                            f"physical range (default {PRIOR_SD:g})")
    model.add_argument("--fit-dt", type=fit_step, default="auto", metavar="S",
                       help="step the fit runs at, s: 'auto' (default: a flight low-passed by jaxheli prepare "
                            "--lowpass at a step of about 1 / (8 x its cut-off), the others at their own), 'full' "
                            "(every flight at its own step) or seconds (the flight must be low-passed below that "
                            "step's Nyquist rate); scores and standard errors use each flight's own step")

    freq = p.add_argument_group(f"the frequency-domain fit (methods {used_by('freq_options')})")
    freq.add_argument("--freq-starts", type=int, default=None, metavar="K",
                      help="Levenberg-Marquardt starts, the best of --freq-screen draws in the box (default "
                           f"{_FREQ_DEFAULTS['starts']})")
    freq.add_argument("--freq-screen", type=int, default=None, metavar="S",
                      help=f"points drawn in the box and scored on J to choose the starts (default "
                           f"{_FREQ_DEFAULTS['screen']})")
    freq.add_argument("--freq-steps", type=int, default=None, metavar="N",
                      help=f"Levenberg-Marquardt step limit of each start (default {_FREQ_DEFAULTS['max_steps']})")
    freq.add_argument("--freq-band", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                      help="fitted band, Hz (default 0.1 Hz to a third of Nyquist, at most 10 Hz)")

    add_sim_options(p.add_argument_group("simulation"), hold="auto")
    add_load_options(p.add_argument_group("reading logs (.px4log .bin .ulg) and checking flights"))
    p.set_defaults(func=_cmd_identify)
    return p


def add_evaluate_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``evaluate`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser("evaluate", help="score a model on a flight (Pearson, TIC, RMSE, fit %%, paper cost)")
    p.add_argument("--model", required=True, help="result.json / parameters JSON, or a named set: table2")
    add_data_option(p, f"the flight scored (default: {DEFAULT_DATA})")
    p.add_argument("--x0", choices=("estimate", "zero", "measured"), default="estimate",
                   help="initial state: least-squares estimate (default, as MATLAB compare), zero (the paper), measured")
    p.add_argument("--out", default=None, help="write the metrics as JSON here")
    add_load_options(p)
    add_sim_options(p, hold="model")
    p.set_defaults(func=_cmd_evaluate)
    return p


def add_synth_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``synth`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser("synth", help="write a piloted synthetic flight (the embedded default unless options change it)")
    p.add_argument("--out", required=True, help="output file, .csv or .npz")
    p.add_argument("--duration", type=float, default=None, help="record length, s (default 80)")
    p.add_argument("--seed", type=int, default=None, help="random seed (default 0)")
    p.add_argument("--gust", type=float, default=0.0, help="gust standard deviation, m/s (default 0)")
    p.set_defaults(func=_cmd_synth)
    return p


def _print_metrics(title: str, block: dict, truth: dict | None = None) -> None:
    """Pearson, TIC, RMSE and fit % per channel, and the paper's cost; the truth's rows beside when given."""
    chans = list(block["pearson"])
    print(title)
    print("  channel     " + "".join(f"{c:>9}" for c in chans))
    for key, label, fmt in (("pearson", "pearson", "9.4f"), ("tic", "TIC", "9.4f"), ("rmse", "RMSE", "9.4f"),
                            ("fit_percent", "fit %", "9.1f")):
        print(f"  {label:<12}" + "".join(f"{block[key][c]:{fmt}}" for c in chans))
        if truth is not None:
            print(f"  {'  truth':<12}" + "".join(f"{truth[key][c]:{fmt}}" for c in chans))
    print(f"  cost (paper Eq. 7): {block['cost']:.6g}" + ("" if truth is None else f" (truth {truth['cost']:.6g})"))


_OBJECTIVE_NAMES = {"output-error": "output error per sample", "pearson": "Pearson cost (paper Eq. 7)",
                    "pem": "prediction error per sample"}
"""How the console names each polish objective (:data:`~jaxheli.optim.polish.POLISH_OBJECTIVES`)."""


def _polish_line(polish: dict, search_cost: str) -> str:
    """The polish in one line: its own objective before -> after, and the search cost (``search_cost``, what IWO /
    GA minimised) at the same two points, marked as not minimised by the polish unless it is the same objective
    (a rise there is no regression)."""
    line = (f"polish: {_OBJECTIVE_NAMES[polish['objective']]} {polish['objective_before']:.6g} -> "
            f"{polish['objective_after']:.6g} (its objective")
    if polish["objective"] == "pearson" == search_cost:
        return line + ", also the search cost)"
    return (line + f"); search cost ({search_cost}) {polish['cost_before']:.6g} -> {polish['cost_after']:.6g}, "
            "not minimised by the polish")


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from ..evaluate import evaluate

    flight = read_flight(args.data or DEFAULT_DATA, args)
    block = evaluate(args.model, flight, outputs=outputs(args.outputs), x0=args.x0, **sim_options(args))
    _print_metrics(f"{args.model} on {flight.source} ({flight.n_samples} samples, dt {flight.dt:.4g} s)", block)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(block, indent=2))
        print(f"wrote {args.out}")
    return 0


def _cmd_identify(args: argparse.Namespace) -> int:
    from ..identify import identify
    from ..at_bounds import TOLERANCE
    from ..results import result_at_bounds, result_modes, save_result
    from ..verify import verify

    options = _identify_options(args)
    records = [read_flight(spec, args) for spec in args.data or [DEFAULT_DATA]]
    train = records[0] if len(records) == 1 else records
    validate = None if not args.validate else read_flight(args.validate, args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if uses(args.method, "checkpoint"):
        options.update(checkpoint=str(out / "checkpoint.eqx"), progress=not args.quiet)
    box = named_box(args.box)
    result = identify(train, method=args.method, validate=validate, trials=args.trials, seed=args.seed,
                      outputs=outputs(args.outputs), lower=np.asarray(box.lower, np.float64),
                      upper=np.asarray(box.upper, np.float64), fit_dt=args.fit_dt, **sim_options(args), **options)
    truth = result.truth or {}
    sources = " + ".join(f.source for f in records)
    _print_metrics(f"{args.method} on the training flight {sources}, initial state estimated"
                   + (" (truth: the flight's true model)" if truth else ""), result.train, truth.get("train"))
    if result.validate is not None:
        _print_metrics(f"validation flight {validate.source}, initial state estimated", result.validate,
                       truth.get("validate"))
        _print_metrics("validation flight, from rest (the paper)", result.validate["zero_initial_state"],
                       (truth.get("validate") or {}).get("zero_initial_state"))
        scored = tuple(c for c in result.settings["outputs"] if c in validate.output_names) or None
        print_verification(verify(result.params, validate, outputs=scored, hold=result.settings["hold"], g=args.g),
                           args.method)
    if result.polish:
        print(_polish_line(result.polish, result.settings["cost"]))
    if result.frequency:
        f = result.frequency
        print(f"CIFER cost J (flight vs model frequency responses, {f['fit']['settings']['band_hz'][0]:g}-"
              f"{f['fit']['settings']['band_hz'][1]:.3g} Hz, coherence >= {f['fit']['settings']['min_coherence']}): "
              f"average {f['j_average']:.1f} ({'acceptable' if f['acceptable'] else 'above 100'}; frequency fit alone "
              f"{f['fit']['j_average']:.1f})")
        print("  " + "  ".join(f"{pair} {j:.0f}" for pair, j in f["j"].items()))
    if truth:
        cr = truth["cramer_rao"]
        print(f"truth within {cr['k']:g} Cramer-Rao standard errors: {len(cr['within'])} of "
              f"{len(cr['identifiable'])} identifiable parameters ({100 * cr['fraction']:.0f} %)")
    print_modes(result_modes(result))
    bounded = ", ".join(f"{a.name} {a.value:.4g} ({a.side} {a.bound:g})" for a in result_at_bounds(result))
    print(f"parameters on a bound of the search box (within {100 * TOLERANCE:g} % of its width; the box, not the "
          f"flight, set them): {bounded or 'none'}")
    print_fixed(result.fixed, result.structure)
    print(f"fit: {result.seconds:.1f} s ({_fit_step_text(result.settings)})")
    for path in save_result(result, out, train, validate):
        print(f"wrote {path}")
    return 0


def _fit_step_text(settings: dict) -> str:
    """Where the stages fitted and how the sticks were held, from a result's ``settings``: ``"at 0.0398 s; sticks
    held first-order; scored at the record's own step"`` or ``"at each record's own step; sticks held zero-order"``."""
    steps = settings.get("fit_dt")
    where = "at each record's own step" if not steps else f"at {' / '.join(f'{d:.4g}' for d in steps)} s"
    hold = {"zoh": "zero-order", "foh": "first-order"}[settings["hold"]]
    return where + f"; sticks held {hold}" + ("; scored at the record's own step" if steps else "")


def _identify_options(args: argparse.Namespace) -> dict:
    """identify's options from the command line: those given, each refused with a one-line ``ValueError`` where
    ``--method`` does not use it, and the frequency fit's (every one, defaults too) where it runs."""
    given = {key: getattr(args, _dest(option)) for key, option in _KEYWORDS.items()}
    given = {key: value for key, value in given.items() if value is not None and value is not False}
    freq = {key: getattr(args, _dest(option)) for key, option in _FREQ_OPTIONS.items()}
    unused = [(key, option) for key, option in _KEYWORDS.items() if key in given and not uses(args.method, key)]
    if not uses(args.method, "freq_options"):
        unused += [("freq_options", option) for key, option in _FREQ_OPTIONS.items() if freq[key] is not None]
    if unused:
        key, option = unused[0]
        raise ValueError(f"{option}: method {args.method!r} does not use it (used by: {used_by(key)})")
    if given.get("chunk", 1) < 1:
        raise ValueError(f"--checkpoint-every: must be >= 1 generation, got {given['chunk']}")
    if uses(args.method, "freq_options"):
        freq = {key: _FREQ_DEFAULTS[key] if value is None else value for key, value in freq.items()}
        given["freq_options"] = {**freq, "band": None if freq["band"] is None else tuple(freq["band"])}
    return given


def _dest(option: str) -> str:
    """The attribute an option's value is stored under."""
    return option.removeprefix("--").replace("-", "_")


def print_fixed(fixed: dict | None, structure: dict | None) -> None:
    """The model-structure determination on the console: one line per fixed parameter (value, where it comes
    from, why), the local fit's sum of squares before and after, and the re-fits its test accepted; one line per
    set a test refused."""
    if fixed is None:
        print("fixed parameters (model-structure determination): not run (--structure)")
        return
    tries = [] if structure is None else structure["rounds"]
    rss = "" if structure is None else (f"; sum of squares {structure['rss_start']:.6g} -> {structure['rss']:.6g}, "
                                        f"{sum(t['accepted'] for t in tries)} of {len(tries)} re-fits accepted")
    print(f"fixed parameters (model-structure determination): {len(fixed) or 'none'}{rss}")
    for name, f in fixed.items():
        print(f"  {name} = {f['value']:.4g} ({f['source']}, round {f['round']}): {f['reason']}")
    for t in tries:
        if not t["accepted"]:
            print(f"  kept free (round {t['round']}): fixing {', '.join(t['fixed'])} raised the sum of squares by "
                  f"{t['rise_sigma2']:.4g} s^2 > {t['limit']:.4g}")


def _cmd_synth(args: argparse.Namespace) -> int:
    from ..io import save
    from ..synth.piloted import default_flight, piloted_flight

    if args.duration is None and args.seed is None and args.gust == 0.0:
        flight = default_flight()
    else:
        flight = piloted_flight(duration=args.duration or 80.0, seed=args.seed or 0, gust=args.gust)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    save(flight, out)
    print(f"{flight!r}\nwrote {out}")
    return 0
