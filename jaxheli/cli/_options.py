"""Options several commands share: the channel list ``--outputs`` and the simulation options ``--hold``,
``--g`` (m/s^2) and ``--segment`` (s), with their conversion to library arguments."""

from __future__ import annotations

import argparse


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
