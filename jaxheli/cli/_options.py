"""Options several commands share: how flights are read (``--strict/--no-strict``, ``--missing-inputs``),
the channel list ``--outputs``, the simulation options ``--hold``, ``--g`` (m/s^2) and ``--segment`` (s),
with their conversion to library arguments, and ``--quiet`` of the long-running commands."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..data.flight import FlightData
from ..flights import load_flight


def add_load_options(p: argparse.ArgumentParser) -> None:
    """Add ``--strict/--no-strict``, ``--missing-inputs`` and ``--channel-map`` to the parser of a command that
    reads flights."""
    p.add_argument("--strict", action=argparse.BooleanOptionalAction, default=True,
                   help="refuse truncated or corrupt logs and implausible values (default); --no-strict loads "
                        "the readable part and records the problems as warnings")
    p.add_argument("--missing-inputs", choices=("error", "zero"), default="error",
                   help="logs (.px4log .bin .ulg): a log without stick channels is an error (default) or read "
                        "with zero sticks")
    p.add_argument("--channel-map", default=None, metavar="FILE.json",
                   help='logs: channels read from other fields, a JSON object such as {"p": ["ATT", "RollRate"], '
                        '"lat": ["RC", "C1", -1.0]} (message or topic, field, optional scale); replaces the '
                        'default map')


def add_quiet_option(p: argparse.ArgumentParser) -> None:
    """Add ``--quiet`` to the parser of a long-running command: without it, the command writes a progress line to
    stderr at each stage and whenever a stage runs long (:func:`jaxheli.reporting`)."""
    p.add_argument("--quiet", action="store_true",
                   help="no progress lines on stderr (errors, warnings and the result still print)")


def finding_line(finding: dict) -> str:
    """One consistency finding (:meth:`jaxheli.gap.Finding.to_json`) as a line; ``*`` marks a significant one."""
    return (f"{'*' if finding['significant'] else ' '} {finding['kind']:<16} {','.join(finding['channels']):<12} "
            f"{finding['message']}")


def _channel_map(path: Path) -> dict:
    """The ``--channel-map`` file: ``{channel: [source, field, ...]}`` (a list of such lists: alternatives)."""
    try:
        mapping = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such channel-map file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a JSON channel map ({exc})") from None
    if not isinstance(mapping, dict):
        raise ValueError(f"{path}: expected a JSON object {{channel: [message, field, scale?]}}")
    return {name: _spec(spec) for name, spec in mapping.items()}


def _spec(spec: object) -> object:
    """A JSON channel spec as the readers take it: a tuple, or a list of tuples for alternatives."""
    if isinstance(spec, list) and spec and all(isinstance(s, list) for s in spec):
        return [tuple(s) for s in spec]
    return tuple(spec) if isinstance(spec, list) else spec


def read_flight(spec: str, args: argparse.Namespace) -> FlightData:
    """The flight ``spec`` names, read under the command's load options; its warnings (e.g. constant channels
    left out) are printed as one-line notices on stderr."""
    options: dict = {"strict": args.strict}
    if args.missing_inputs != "error":
        options["missing_inputs"] = args.missing_inputs
    if args.channel_map:
        options["channels"] = _channel_map(Path(args.channel_map))
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
