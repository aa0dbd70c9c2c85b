"""Command line: ``jaxheli identify | evaluate | synth | bench`` (``jaxheli COMMAND --help``)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .benchmark.command import add_parser as add_bench_parser
from .distributed import add_parser as add_trials_scaling_parser
from .gap.blind import add_parser as add_blind_parser
from .gap.consistency import add_parser as add_check_parser
from .gap.diagnose import add_parser as add_diagnose_parser
from .gap.localise_cli import add_parser as add_localise_parser
from .report.command import add_parser as add_report_parser

DEFAULT_DATA = "default"
"""Name of the embedded synthetic flight (generated on the fly, see :func:`jaxheli.default_flight`)."""


def _load_flight(spec: str):
    from .io import load
    from .synth.piloted import default_flight

    return default_flight() if spec == DEFAULT_DATA else load(spec)


def _outputs(text: str | None) -> tuple[str, ...] | None:
    return None if not text else tuple(c.strip() for c in text.split(",") if c.strip())


def _add_sim_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--outputs", default=None, help="comma-separated channels, e.g. p,q,phi,theta (default: all measured)")
    p.add_argument("--hold", choices=("zoh", "foh"), default="zoh", help="input hold between samples (default zoh)")
    p.add_argument("--g", type=float, default=9.81, help="gravity, m/s^2 (default 9.81)")
    p.add_argument("--segment", type=float, default=None,
                   help="restart from measured states every SECONDS (multiple shooting); default: one long run")


def _sim_options(args: argparse.Namespace) -> dict:
    return {"hold": args.hold, "g": args.g, "segment": args.segment}


def _print_metrics(title: str, block: dict) -> None:
    chans = list(block["pearson"])
    print(title)
    print("  channel  " + "".join(f"{c:>9}" for c in chans))
    for key, label, fmt in (("pearson", "pearson", "9.4f"), ("tic", "TIC", "9.4f"), ("fit_percent", "fit %", "9.1f")):
        print(f"  {label:<9}" + "".join(f"{block[key][c]:{fmt}}" for c in chans))
    print(f"  cost (paper Eq. 7): {block['cost']:.6g}")


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from .evaluate import evaluate

    flight = _load_flight(args.data)
    x0 = args.x0
    block = evaluate(args.model, flight, outputs=_outputs(args.outputs), x0=x0, **_sim_options(args))
    _print_metrics(f"{args.model} on {flight.source} ({flight.n_samples} samples, dt {flight.dt:.4g} s)", block)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(block, indent=2))
        print(f"wrote {args.out}")
    return 0


def _cmd_identify(args: argparse.Namespace) -> int:
    from .identify import identify
    from .results import save_result

    train = _load_flight(args.train)
    validate = None if not args.validate else train if args.validate == args.train else _load_flight(args.validate)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = identify(
        train,
        method=args.method,
        validate=validate,
        iterations=args.iterations,
        trials=args.trials,
        seed=args.seed,
        outputs=_outputs(args.outputs),
        checkpoint=str(out / "checkpoint.eqx") if args.method != "pem" else None,
        resume=args.resume,
        search_precision=args.search_precision,
        **_sim_options(args),
    )
    _print_metrics(f"{args.method} on the training flight {train.source}", result.train)
    if result.validate is not None:
        _print_metrics(f"validation flight {validate.source}, initial state estimated", result.validate)
        _print_metrics("validation flight, from rest (the paper)", result.validate["zero_initial_state"])
    if result.polish:
        print(f"polish: cost {result.polish['cost_before']:.6g} -> {result.polish['cost_after']:.6g}")
    for path in save_result(result, out, train, validate):
        print(f"wrote {path}")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    from .io import save_csv, save_npz
    from .synth.piloted import default_flight, piloted_flight

    if args.duration is None and args.seed is None and args.gust == 0.0:
        flight = default_flight()
    else:
        flight = piloted_flight(duration=args.duration or 80.0, seed=args.seed or 0, gust=args.gust)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    (save_npz if out.suffix.lower() == ".npz" else save_csv)(flight, out)
    print(f"{flight!r}\nwrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``jaxheli`` argument parser (all sub-commands)."""
    parser = argparse.ArgumentParser(
        prog="jaxheli",
        description="System identification of small unmanned helicopters (Mettler's 13-state hover model) in JAX.",
    )
    parser.add_argument("--float32", action="store_true", help="compute in float32 (faster; default float64)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("identify", help="fit the 40 parameters to a flight (IWO, GA, PEM, IWO + polish)")
    p.add_argument("--method", choices=("iwo", "ga", "pem", "iwo+polish"), default="iwo+polish")
    p.add_argument("--train", default=DEFAULT_DATA, help="training flight file or 'default' (the embedded flight)")
    p.add_argument("--validate", default=None, help="validation flight file (optional)")
    p.add_argument("--out", default="jaxheli-result", help="output folder (result.json, result.npz, PNGs)")
    p.add_argument("--iterations", type=int, default=1000, help="IWO / GA generations (default 1000, the paper)")
    p.add_argument("--trials", type=int, default=1, help="independent trials for 95%% intervals (the paper: 10)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.eqx")
    p.add_argument("--search-precision", choices=("float32", "float64"), default="float32",
                   help="arithmetic of the IWO / GA population scoring (default float32: fast, checked against float64)")
    _add_sim_options(p)
    p.set_defaults(func=_cmd_identify)

    p = sub.add_parser("evaluate", help="score a model on a flight (Pearson, TIC, RMSE, fit %%, paper cost)")
    p.add_argument("--model", required=True, help="result.json / parameters JSON, or a named set: table2")
    p.add_argument("--data", default=DEFAULT_DATA, help="flight file (.mat .csv .npz .px4log .bin .ulg) or 'default'")
    p.add_argument("--x0", choices=("estimate", "zero", "measured"), default="estimate",
                   help="initial state: least-squares estimate (default, as MATLAB compare), zero (the paper), measured")
    p.add_argument("--out", default=None, help="write the metrics as JSON here")
    _add_sim_options(p)
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser("synth", help="write a piloted synthetic flight (the embedded default unless options change it)")
    p.add_argument("--out", required=True, help="output file, .csv or .npz")
    p.add_argument("--duration", type=float, default=None, help="record length, s (default 80)")
    p.add_argument("--seed", type=int, default=None, help="random seed (default 0)")
    p.add_argument("--gust", type=float, default=0.0, help="gust standard deviation, m/s (default 0)")
    p.set_defaults(func=_cmd_synth)

    add_check_parser(sub)
    add_localise_parser(sub)
    add_diagnose_parser(sub)
    add_blind_parser(sub)
    add_bench_parser(sub)
    add_trials_scaling_parser(sub)
    add_report_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxheli`` command."""
    args = build_parser().parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", not args.float32)
    try:
        return args.func(args)
    except (FileNotFoundError, ValueError) as err:
        print(f"jaxheli {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
