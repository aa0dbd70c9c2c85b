"""``jaxheli prepare --data FILE[:t0-t1] [--check] [--correct] [--trim N] [--lowpass HZ] [--resample DT]
--out FILE.npz``: the preparation chain of a flight (:func:`jaxheli.gap.prepare.prepare`) written as an NPZ that
``identify``, ``evaluate`` and ``diagnose`` read, every step recorded in its ``metadata["preprocessing"]``. The old
``jaxheli prepare FILE [--window T0:T1]`` is still read."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..flights import parse_spec
from ..gap.prepare import prepare
from ..io import save_npz
from ._options import OldForm, add_data_option, add_load_options, finding_line, read_flight


def add_prepare_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``prepare`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser(
        "prepare", help="check, correct, trim, low-pass and resample a flight into an NPZ for the other commands",
        description="Steps run in this order, each optional: the window of --data FILE:t0-t1, --trim, "
        "--check/--correct, --lowpass, --resample. E.g. the training flight of benchmarks/paper_comparison.py: "
        "jaxheli prepare --data Data_graphready.mat --trim 50 --correct --lowpass 3 --out flight_a.npz",
    )
    add_data_option(p, "the flight prepared", required=True, positional_form=True)
    p.add_argument("--out", required=True, metavar="FILE.npz", help="prepared flight (NPZ)")
    p.add_argument("--window", action=OldForm, old="--window T0:T1", new="--data FILE:T0-T1", adopt=_adopt_window)
    p.add_argument("--trim", type=int, default=0, metavar="N", help="drop N samples at each end (resampling ringing)")
    p.add_argument("--check", action="store_true", help="run the consistency check; findings go in the file")
    p.add_argument("--correct", action="store_true", help="apply the check's significant findings (implies --check)")
    p.add_argument("--lowpass", type=float, default=None, metavar="HZ",
                   help="zero-phase Butterworth low-pass (order 4) of inputs and outputs, Hz")
    p.add_argument("--resample", type=float, default=None, metavar="DT", help="resample to this step, s")
    add_load_options(p)
    p.set_defaults(func=_cmd_prepare)
    return p


def _adopt_window(namespace: argparse.Namespace, text: str) -> None:
    """The old ``--window T0:T1`` as the window of ``--data FILE:T0-T1``."""
    t0, colon, t1 = text.partition(":")
    spec = f"{namespace.data}:{t0}-{t1}"
    if parse_spec(namespace.data)[1:] != (None, None):
        raise ValueError(f"{namespace.data} already has a window")
    if not colon or parse_spec(spec) == (spec, None, None):
        raise ValueError(f"expected T0:T1 in seconds (e.g. 10:70), got {text!r}")
    namespace.data = spec


def _cmd_prepare(args: argparse.Namespace) -> int:
    if args.trim < 0:
        raise ValueError(f"--trim: must be >= 0 samples, got {args.trim}")
    out = Path(args.out)
    if out.suffix.lower() != ".npz":
        raise ValueError(f"--out: {out}: the prepared flight is written as .npz")
    name, t0, t1 = parse_spec(args.data)
    window = None if t0 is None and t1 is None else (t0, t1)
    flight = prepare(read_flight(name, args), window=window, trim_samples=args.trim,
                     check_data=args.check, correct_data=args.correct, lowpass_hz=args.lowpass, dt=args.resample)
    for f in flight.metadata.get("consistency", []):
        print(finding_line(f))
    steps = [s["step"] for s in flight.metadata.get("preprocessing", [])]
    out.parent.mkdir(parents=True, exist_ok=True)
    save_npz(flight, out)
    print(f"{flight!r}\nsteps: {', '.join(steps) or 'none'}\nwrote {out}")
    return 0
