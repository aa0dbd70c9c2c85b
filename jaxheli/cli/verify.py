"""``jaxheli verify``: time-domain verification of a model on flights it was not fitted to, in short runs."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..flights import DEFAULT_DATA
from ._options import add_data_option, add_load_options, add_quiet_option, outputs, read_flight


def add_verify_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``verify`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser("verify", help="verify a model on flights in short runs (Tischler ch. 14): TIC, J_rms, "
                                             "Pearson, fit %% per channel, the model's modes, a PNG per run")
    p.add_argument("--model", required=True, help="result.json / parameters JSON, or a named set: table2")
    add_data_option(p, f"the flight(s) the model is verified on (default: {DEFAULT_DATA})", several=True)
    p.add_argument("--run-length", nargs="+", default=["5"], metavar="SECONDS",
                   help="run length(s), s, or 'whole' for one run over the window (default 5; the book's practice: "
                        "5 10 whole)")
    p.add_argument("--out", required=True, help="output folder (verification.json, verification.csv, a PNG per run)")
    p.add_argument("--outputs", default=None, help="comma-separated channels (default: all measured but a, b)")
    p.add_argument("--hold", choices=("zoh", "foh"), default=None,
                   help="input hold between samples (default: the one a result.json was fitted with, else zoh)")
    p.add_argument("--g", type=float, default=9.81, help="gravity, m/s^2 (default 9.81)")
    add_load_options(p)
    add_quiet_option(p)
    p.set_defaults(func=_cmd_verify)
    return p


def run_lengths(values: list[str]) -> list[float | None]:
    """``--run-length`` values as seconds (``None`` for ``whole``)."""
    out: list[float | None] = []
    for text in values:
        try:
            out.append(None if text == "whole" else float(text))
        except ValueError:
            raise ValueError(f"--run-length: expected seconds or 'whole', got {text!r}") from None
    return out


def print_verification(v, model: str) -> None:
    """One verification (:class:`jaxheli.verify.Verification`) as a table: its pooled scores per channel and
    overall, then its notes."""
    from ..verify import J_RMS_GUIDE, TIC_GUIDE

    runs = "one run over the whole window" if v.run_length is None else f"{len(v.runs)} run(s) of {v.run_length:g} s"
    print(f"{model} on {v.source} ({v.runs[0].start_s:.6g}-{v.runs[-1].end_s:.6g} s): {runs}, each from its "
          "least-squares state and output bias; pooled scores (J_rms weights W = 1/std^2)")
    chans = [*v.channels, "overall"]
    print("  " + " " * 18 + "".join(f"{c:>10}" for c in chans))
    rows = (("tic", f"TIC (<= {TIC_GUIDE:g})", "10.3f"), ("j_rms", f"J_rms (<= {J_RMS_GUIDE:g})", "10.4g"),
            ("pearson", "Pearson", "10.3f"), ("fit_percent", "fit %", "10.4g"))
    for key, label, fmt in rows:
        print(f"  {label:<18}" + "".join(f"{v.pooled[key][c]:{fmt}}" for c in chans))
    for note in v.notes:
        print(f"  note: {note}")


def print_modes(found) -> None:
    """The model's modes (:func:`jaxheli.modes.modes`), one line each."""
    print("modes of A (eigenvalue, name, dominant states by participation, natural frequency, damping, time to "
          "double or half):")
    for mode in found:
        print("  " + mode.describe())


def _cmd_verify(args: argparse.Namespace) -> int:
    from ..verify import save_verification, verify

    lengths = run_lengths(args.run_length)
    found = []
    for spec in args.data or [DEFAULT_DATA]:
        flight = read_flight(spec, args)
        for length in lengths:
            found.append(verify(args.model, flight, run_length=length, outputs=outputs(args.outputs), hold=args.hold,
                                g=args.g))
            print_verification(found[-1], args.model)
    print_modes(found[0].modes)
    files = save_verification(found, args.model, Path(args.out))
    print(f"wrote {files[0]}, {files[1]} and {len(files) - 2} PNG(s) under {args.out}")
    return 0
