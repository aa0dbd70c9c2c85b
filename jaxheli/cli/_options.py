"""Options several commands share: how flights are read (``--strict/--no-strict``, ``--missing-inputs``),
the channel list ``--outputs`` and the simulation options ``--hold``, ``--g`` (m/s^2) and ``--segment`` (s),
with their conversion to library arguments."""

from __future__ import annotations

import argparse
import sys

from ..data.flight import FlightData
from ..flights import load_flight


def add_load_options(p: argparse.ArgumentParser) -> None:
    """Add ``--strict/--no-strict`` and ``--missing-inputs`` to the parser of a command that reads flights."""
    p.add_argument("--strict", action=argparse.BooleanOptionalAction, default=True,
                   help="refuse truncated or corrupt logs and implausible values (default); --no-strict loads "
                        "the readable part and records the problems as warnings")
    p.add_argument("--missing-inputs", choices=("error", "zero"), default="error",
                   help="logs (.px4log .bin .ulg): a log without stick channels is an error (default) or read "
                        "with zero sticks")


def finding_line(finding: dict) -> str:
    """One consistency finding (:meth:`jaxheli.gap.Finding.to_json`) as a line; ``*`` marks a significant one."""
    return (f"{'*' if finding['significant'] else ' '} {finding['kind']:<16} {','.join(finding['channels']):<12} "
            f"{finding['message']}")


def read_flight(spec: str, args: argparse.Namespace) -> FlightData:
    """The flight ``spec`` names, read under the command's load options; its warnings (e.g. constant channels
    left out) are printed as one-line notices on stderr."""
    options = {"strict": args.strict}
    if args.missing_inputs != "error":
        options["missing_inputs"] = args.missing_inputs
    flight = load_flight(spec, **options)
    for warning in flight.metadata.get("warnings", []):
        print(f"note: {flight.source}: {warning}", file=sys.stderr)
    return flight


def add_sim_options(p: argparse.ArgumentParser) -> None:
    """Add ``--outputs``, ``--hold``, ``--g`` and ``--segment`` to the parser of a command that simulates."""
    p.add_argument("--outputs", default=None, help="comma-separated channels, e.g. p,q,phi,theta (default: all measured)")
    p.add_argument("--hold", choices=("zoh", "foh"), default="zoh", help="input hold between samples (default zoh)")
    p.add_argument("--g", type=float, default=9.81, help="gravity, m/s^2 (default 9.81)")
    p.add_argument("--segment", type=float, default=None,
                   help="restart from measured states every SECONDS (multiple shooting); default: one long run")


def sim_options(args: argparse.Namespace) -> dict:
    """``hold``, ``g`` and ``segment`` as keyword arguments of the simulator (:func:`jaxheli.make_simulator`)."""
    return {"hold": args.hold, "g": args.g, "segment": args.segment}


def outputs(text: str | None) -> tuple[str, ...] | None:
    """The channels of a comma-separated ``--outputs`` value; ``None`` (the library's default) when not given."""
    return None if not text else tuple(c.strip() for c in text.split(",") if c.strip())
