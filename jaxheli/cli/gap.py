"""``jaxheli check | localise | diagnose | blind``: data consistency, where a model misses a flight, which
unmodelled effect explains the gap, and the blind check of that diagnosis."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..effects import registry as fx
from ..evaluate import resolve_params
from ..flights import DEFAULT_DATA
from ..benchmark.blind import BASES, BOXES, TRUTH_CLASSES, TRUTHS_SIM, markdown, resume_benchmark, run_benchmark
from ..benchmark.blind import summarise_records
from ..gap.compare import localise_model, write_localisation
from ..gap.consistency import MAX_TRAVEL_M, check, write_check
from ..gap.diagnose import diagnose, write_diagnosis
from ..gap.fit_effect import MAX_STEPS
from ..gap.predictor import RESTART, RESTARTS, SEGMENT
from ..gap.significance import EFFECT_SIGMA, LR_P, MIN_SHRINK
from ..gap.prepare import SAMPLE_S, prepare
from ..model import G_SI
from .diagnosis_text import ranking_table, verdict_line
from ._options import (add_data_option, add_flight_option, add_load_options, add_quiet_option, add_sim_options,
                       finding_line, outputs, read_flight, sim_options)


def add_check_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``jaxheli check --data FILE[:t0-t1] --out DIR`` on the CLI's sub-command parsers (the old
    ``jaxheli check FILE`` still read)."""
    p = subparsers.add_parser("check", help="data-consistency check of a flight (kinematics, velocity frame, biases)")
    add_data_option(p, "the flight checked", required=True, positional_form=True)
    p.add_argument("--out", default="jaxheli-check", help="output folder (consistency.json, consistency.png)")
    p.add_argument("--max-travel", type=float, default=MAX_TRAVEL_M,
                   help=f"plausible net displacement of the record, m (default {MAX_TRAVEL_M:g}: a hover test)")
    add_load_options(p)
    p.set_defaults(func=_cmd_check)
    return p


def add_localise_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``jaxheli localise --model M --data FILE[:t0-t1] --out DIR`` on the CLI's sub-command parsers."""
    p = subparsers.add_parser("localise", help="where a model misses a flight: by channel, band, time window, lag")
    p.add_argument("--model", required=True, help="result.json / parameters JSON, or a named set: table2")
    add_data_option(p, f"the flight the model is compared with (default: {DEFAULT_DATA})")
    p.add_argument("--x0", choices=("estimate", "zero", "measured"), default="estimate", help="initial state")
    p.add_argument("--window", type=float, default=5.0, help="time window, s (default 5)")
    p.add_argument("--max-lag", type=float, default=1.0, help="largest input-residual lag, s (default 1)")
    p.add_argument("--out", default="jaxheli-localise", help="output folder (localisation.json, PNGs)")
    add_load_options(p)
    add_sim_options(p)
    p.set_defaults(func=_cmd_localise)
    return p


def _add_restart_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--restart", choices=RESTARTS, default=RESTART,
                   help="each prediction restarts from the Kalman filter's state of the readings before it "
                        "(filter) or from that state re-estimated by least squares on the segment's own readings "
                        "(segment; default %(default)s: thresholds.json)")


def add_diagnose_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``jaxheli diagnose --model M --data FILE[:t0-t1] --validate FILE[:t0-t1] --out DIR`` on the CLI's
    sub-command parsers (``--train`` the role name of ``--data``)."""
    p = subparsers.add_parser("diagnose", help="which unmodelled effect explains a model's gap, and how far it shrinks")
    p.add_argument("--model", required=True, help="result.json / parameters JSON, or a named set: table2")
    add_data_option(p, "the training flight, the effects are fitted on", aliases=("--train",), required=True)
    add_flight_option(p, "--validate", "the held-out flight the shrink is measured on", required=True)
    p.add_argument("--out", default="jaxheli-diagnose", help="output folder (diagnosis.json, consistency.json, PNGs)")
    p.add_argument("--outputs", default=None, help="comma-separated channels (default: those both flights share)")
    p.add_argument("--effects", default=",".join(fx.ALL),
                   help=f"comma-separated candidates (default: {','.join(fx.ALL)})")
    p.add_argument("--segment", type=float, default=SEGMENT,
                   help="restart interval of the predictions, s (default %(default)g: thresholds.json)")
    _add_restart_option(p)
    p.add_argument("--track", type=float, default=None,
                   help="restart filter's process noise per sample, in measurement-noise stds (default: the level "
                        "of 0.1-10 that suits the model best on the training flight)")
    p.add_argument("--top", type=int, default=3, help="significant effects fitted jointly (default 3)")
    p.add_argument("--g", type=float, default=G_SI, help="gravity, m/s^2 (default 9.81)")
    p.add_argument("--max-steps", type=int, default=MAX_STEPS,
                   help="Levenberg-Marquardt steps per candidate fit (default %(default)s: the blind check's, on which "
                        "the thresholds were set)")
    p.add_argument("--min-shrink", type=float, default=MIN_SHRINK,
                   help="noise floor of the held-out shrink, %% (default %(default)g: set on effect-free flights "
                        "with identified base models); below it a candidate is significant only when its training "
                        f"likelihood ratio has p <= {LR_P:g} and its held-out shrink stands {EFFECT_SIGMA:g} standard "
                        "errors above zero")
    p.add_argument("--frozen-base", action="store_true",
                   help="hold the base model's parameters fixed while fitting each effect (default: re-identify them "
                        "jointly with it and credit it only beyond the base model re-fitted alone)")
    p.add_argument("--correct", action="store_true",
                   help="apply each flight's significant consistency findings (jaxheli check) before diagnosing")
    p.add_argument("--train-trim", type=int, default=0,
                   help="drop this many samples at each end of the training flight")
    p.add_argument("--train-lowpass", type=float, default=None, help="zero-phase low-pass of the training flight, Hz")
    p.add_argument("--train-dt", type=float, default=None, help="resample the training flight to this step, s")
    p.add_argument("--dt", type=float, default=SAMPLE_S,
                   help="step both flights are diagnosed at, s: one sampled faster is low-passed (zero-phase, at 0.35 "
                        "of the new rate) and resampled to it (default %(default)g: thresholds.json, the step of the "
                        "flights the thresholds were set on; 0: each flight at its own step)")
    add_load_options(p)
    add_quiet_option(p)
    p.set_defaults(func=_cmd_diagnose)
    return p


def add_blind_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``jaxheli blind --seeds N [--kinds ...] --out DIR`` on the CLI's sub-command parsers."""
    p = subparsers.add_parser("blind", help="blind check of the effect diagnosis on synthetic flights")
    p.add_argument("--truth", choices=tuple(TRUTHS_SIM), default="library",
                   help="truth simulator: the library's piloted flights, or the independent one in "
                        "jaxheli.benchmark.truth (default library)")
    p.add_argument("--kinds", nargs="+", choices=tuple(dict.fromkeys(k for ks in TRUTHS_SIM.values() for k in ks)),
                   help="effect kinds of that truth (default all + none)")
    p.add_argument("--summarise", metavar="BLIND_JSON", type=Path,
                   help="run nothing: summarise the records of an earlier run's blind.json again (today's table, "
                        "e.g. after a column was added) and write --out/blind.md")
    p.add_argument("--resume", metavar="BLIND_JSON", type=Path,
                   help="fly the trials a stopped run's blind.json does not hold, with its settings and seeds (already "
                        "in the seed ledger), under the rules and code it started with (refused otherwise), and grow "
                        "that record in place; only --workers is read beside it")
    p.add_argument("--split", choices=("design", "calibration", "test"), default="design",
                   help="seed range of the protocol in jaxheli/gap/thresholds.json: design (where rules are tried), "
                        "calibration (sets the thresholds), test (looked at once per rule change and simulator, never "
                        "changes a rule: a second test look under the same rules is refused; default design)")
    p.add_argument("--seeds", type=int, default=2, help="trials per effect kind, the split's first seeds (default 2)")
    p.add_argument("--control-seeds", type=int, default=None,
                   help="trials of the effect-free control (kind none; default twice --seeds)")
    p.add_argument("--skip-seeds", type=int, default=0,
                   help="start this many seeds into the split (e.g. --split test --skip-seeds 1000: test seeds from "
                        "2000; default 0). A seed once flown, in any split, is spent: every seed a run draws, "
                        "controls included, is appended to the seed ledger (jaxheli/gap/seed_ledger.jsonl, "
                        "or $JAXHELI_LEDGER) before it flies, and a spent seed is refused with the --skip-seeds of "
                        "the first unspent ones")
    p.add_argument("--refly-design", action="store_true",
                   help="fly spent design seeds again (to compare a rule before and after on the same flights; "
                        "still recorded); calibration and test seeds are never flown twice")
    p.add_argument("--truths", choices=tuple(TRUTH_CLASSES), default="narrow",
                   help="class of truth hover models: narrow (Table 2, R-50 and both perturbed by 30 %%), or wide "
                        "(both perturbed, with heave, speed, pedal and collective couplings outside the authors' box; "
                        "default narrow)")
    p.add_argument("--base", choices=BASES, default="pem",
                   help="how each trial's base model is identified on its training flight: PEM, IWO + polish, or "
                        "identify's default method as a user of the command line gets it (default pem)")
    p.add_argument("--box", choices=tuple(BOXES), default="hull",
                   help="box the base model is identified and diagnosed in: the hull of both truth classes, or "
                        "the command line's default (the authors' TREX box, which the R-50 truths leave; default "
                        "hull)")
    p.add_argument("--segment", type=float, default=SEGMENT,
                   help="restart interval of the diagnosis's predictions, s (default %(default)g: thresholds.json)")
    _add_restart_option(p)
    p.add_argument("--duration", type=float, default=30.0, help="flight length, s (default 30)")
    p.add_argument("--dt", type=float, default=0.05, help="sample time, s (default 0.05)")
    p.add_argument("--max-steps", type=int, default=MAX_STEPS, help="LM steps per candidate fit (default %(default)s)")
    p.add_argument("--pem-steps", type=int, default=100,
                   help="PEM steps identifying each trial's base model on its training flight (default 100)")
    p.add_argument("--iwo-seeds", type=int, default=3,
                   help="the first N seeds of every kind run again with an IWO + polish base model, reported beside "
                        "PEM on the same trials (default 3; 0: PEM only)")
    p.add_argument("--iterations", type=int, default=1000,
                   help="IWO generations of those base models (default 1000, the paper)")
    p.add_argument("--workers", type=int, default=1,
                   help="trials run in parallel processes, each on a core of its own (default 1)")
    p.add_argument("--out", default="jaxheli-blind", help="output folder (blind.json, blind.md)")
    add_quiet_option(p)
    run_options = {a.dest: a.default for a in p._actions if a.option_strings and a.dest not in _BESIDE_RESUME}
    p.set_defaults(func=_cmd_blind, run_options=run_options)
    return p


_BESIDE_RESUME = ("help", "resume", "workers", "quiet")
"""Options ``jaxheli blind --resume`` reads: every other one comes from the resumed run's record."""


def _cmd_check(args: argparse.Namespace) -> int:
    flight = read_flight(args.data, args)
    findings = check(flight, args.max_travel)
    print(f"consistency of {flight.source} ({flight.n_samples} samples, dt {flight.dt:.4g} s); * = significant")
    for f in findings:
        print(finding_line(f.to_json()))
    for path in write_check(flight, findings, args.out):
        print(f"wrote {path}")
    return 0


def _cmd_localise(args: argparse.Namespace) -> int:
    flight = read_flight(args.data or DEFAULT_DATA, args)
    theta = resolve_params(args.model)
    report, _ = localise_model(
        theta, flight, outputs=outputs(args.outputs), x0=args.x0,
        localise_options={"window_seconds": args.window, "max_lag_seconds": args.max_lag}, **sim_options(args),
    )
    s = report.summary
    print(f"gap of {args.model} on {flight.source}:")
    print("  nmse   " + "  ".join(f"{n} {c.nmse:.3g}" for n, c in report.channel.items()))
    print(f"  worst channel {s.worst_channel} (nmse {s.worst_channel_nmse:.3g}); "
          f"{100 * s.worst_band_share:.0f}% of it in {s.worst_band_hz[0]:g}-{s.worst_band_hz[1]:.3g} Hz "
          f"({s.worst_band_verdict})")
    print(f"  top window {s.top_window_s[0]:.4g}-{s.top_window_s[1]:.4g} s "
          f"({100 * s.top_window_share:.0f}% of the energy); amplitude link: {s.amplitude_link}")
    lag = s.strongest_lag
    print(f"  strongest lag {lag.name} {lag.peak_lag_s:.3g} s, rho {lag.peak_value:.3f} (threshold {lag.threshold:.3f})")
    for path in write_localisation(report, theta, flight, args.out):
        print(f"wrote {path}")
    return 0


def _cmd_diagnose(args: argparse.Namespace) -> int:
    chosen = tuple(e.strip() for e in args.effects.split(",") if e.strip())
    unknown = [e for e in chosen if e not in fx.ALL]
    if unknown or not chosen:
        raise SystemExit(f"jaxheli diagnose: --effects: unknown effect(s) {unknown}; candidates are {fx.ALL}")
    theta = resolve_params(args.model)
    train = prepare(read_flight(args.data, args), trim_samples=args.train_trim, lowpass_hz=args.train_lowpass,
                    dt=args.train_dt)
    validate = read_flight(args.validate, args)
    diagnosis = diagnose(
        theta, train, validate, name=args.model, outputs=outputs(args.outputs), effects=chosen,
        segment=args.segment, restart=args.restart, top=args.top, g=args.g, max_steps=args.max_steps,
        min_shrink=args.min_shrink, track=args.track, joint=not args.frozen_base, dt=args.dt or None,
        correct=args.correct,
    )
    found = diagnosis.attribution
    steps = " and ".join(dict.fromkeys(f"{f.dt:.4g}" for f in diagnosis.flights.values()))
    print(f"diagnosis of {args.model}: trained on {train.source}, validated on {validate.source} "
          f"(step {steps} s, segment {args.segment:g} s, restart {args.restart}, restart filter level "
          f"{found.track:g}; channels {','.join(diagnosis.outputs)})")
    print(f"found: {diagnosis.headline}")
    for line in ranking_table(diagnosis):
        print(line)
    print(f"verdict: {verdict_line(found.verdict)}")
    if found.final is not None:
        print(f"its size re-identified with the base model on both flights: {found.final.fitted.summary}")
    for path in write_diagnosis(diagnosis, theta, validate, args.out):
        print(f"wrote {path}")
    return 0


def _cmd_blind(args: argparse.Namespace) -> int:
    if args.summarise is not None:
        table = markdown(summarise_records(args.summarise))
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "blind.md").write_text(table + "\n")
        print(table)
        print(f"wrote {Path(args.out) / 'blind.md'} (records of {args.summarise})")
        return 0
    if args.resume is not None:
        given = ["--" + d.replace("_", "-") for d, v in args.run_options.items() if getattr(args, d) != v]
        if given:
            raise SystemExit(f"jaxheli blind --resume: {', '.join(given)} not read: a resumed run keeps the settings "
                             f"its record holds ({args.resume}); beside --resume give only --workers")
        summary = resume_benchmark(args.resume, workers=args.workers)
        print(markdown(summary))
        print(f"runtime {summary['runtime_s']:.0f} s; wrote {args.resume} and blind.md beside it")
        return 0
    kinds = args.kinds or list(TRUTHS_SIM[args.truth])
    summary = run_benchmark(kinds, args.seeds, args.out, workers=args.workers, iwo_seeds=args.iwo_seeds,
                            truth=args.truth, split=args.split, control_seeds=args.control_seeds,
                            skip_seeds=args.skip_seeds, refly_design=args.refly_design, duration=args.duration,
                            dt=args.dt, max_steps=args.max_steps, pem_steps=args.pem_steps,
                            iterations=args.iterations, box=args.box, segment=args.segment, restart=args.restart,
                            base=args.base, truths=args.truths)
    print(markdown(summary))
    print(f"runtime {summary['runtime_s']:.0f} s; wrote {Path(args.out) / 'blind.json'} and blind.md")
    return 0
