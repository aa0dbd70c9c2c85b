"""``jaxheli prepare FILE [--check] [--correct] [--trim N] [--lowpass HZ] [--resample DT] [--window T0:T1]
--out FILE.npz``: the preparation chain of a flight (:func:`jaxheli.prepare`) written as an NPZ that
``identify``, ``evaluate`` and ``diagnose`` read, every step recorded in its ``metadata["preprocessing"]``."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..gap.prepare import prepare
from ..io import save_npz
from ._options import add_load_options, finding_line, read_flight


def add_prepare_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``prepare`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser(
        "prepare", help="check, correct, trim, low-pass and resample a flight into an NPZ for the other commands",
        description="Steps run in this order, each optional: --window, --trim, --check/--correct, --lowpass, "
        "--resample. E.g. the training flight of benchmarks/paper_comparison.py: "
        "jaxheli prepare Data_graphready.mat --trim 50 --correct --lowpass 3 --out flight_a.npz",
    )
    p.add_argument("file", metavar="FILE", help="flight file (.mat .csv .npz .px4log .bin .ulg) or 'default'")
    p.add_argument("--out", required=True, metavar="FILE.npz", help="prepared flight (NPZ)")
    p.add_argument("--window", default=None, metavar="T0:T1", help="keep T0 <= t <= T1 (s, the file's time axis)")
    p.add_argument("--trim", type=int, default=0, metavar="N", help="drop N samples at each end (resampling ringing)")
    p.add_argument("--check", action="store_true", help="run the consistency check; findings go in the file")
    p.add_argument("--correct", action="store_true", help="apply the check's significant findings (implies --check)")
    p.add_argument("--lowpass", type=float, default=None, metavar="HZ",
                   help="zero-phase Butterworth low-pass (order 4) of inputs and outputs, Hz")
    p.add_argument("--resample", type=float, default=None, metavar="DT", help="resample to this step, s")
    add_load_options(p)
    p.set_defaults(func=_cmd_prepare)
    return p


def _window(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    parts = text.split(":")
    try:
        t0, t1 = (float(v) for v in parts)
    except ValueError:
        raise ValueError(f"--window: expected T0:T1 in seconds (e.g. 10:70), got {text!r}") from None
    if not t0 < t1:
        raise ValueError(f"--window: T0 must be below T1, got {text!r}")
    return t0, t1


def _cmd_prepare(args: argparse.Namespace) -> int:
    if args.trim < 0:
        raise ValueError(f"--trim: must be >= 0 samples, got {args.trim}")
    out = Path(args.out)
    if out.suffix.lower() != ".npz":
        raise ValueError(f"--out: {out}: the prepared flight is written as .npz")
    flight = prepare(read_flight(args.file, args), window=_window(args.window), trim_samples=args.trim,
                     check_data=args.check, correct_data=args.correct, lowpass_hz=args.lowpass, dt=args.resample)
    for f in flight.metadata.get("consistency", []):
        print(finding_line(f))
    steps = [s["step"] for s in flight.metadata.get("preprocessing", [])]
    out.parent.mkdir(parents=True, exist_ok=True)
    save_npz(flight, out)
    print(f"{flight!r}\nsteps: {', '.join(steps) or 'none'}\nwrote {out}")
    return 0
