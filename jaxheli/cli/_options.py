"""Options several commands share: the flights a command reads (``--data FILE[:t0-t1]``, the one grammar of
every command, and the old forms it replaced), how they are read (``--strict/--no-strict``,
``--missing-inputs``), the channel list ``--outputs``, the simulation options ``--hold``, ``--g`` (m/s^2) and
``--segment`` (s), with their conversion to library arguments, and ``--quiet`` of the long-running commands."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..data.flight import FlightData
from ..flights import load_flight

Options = argparse.ArgumentParser | argparse._ArgumentGroup
"""Where an option is added: a command's parser, or one of its groups (the sections of its ``--help``)."""

FLIGHT = "FILE[:t0-t1]"
"""How every option that names a flight shows it: a file, optionally cut to a window (s)."""

FLIGHT_HELP = ("a flight file (.mat .csv .npz .px4log .bin .ulg, a 'jaxheli prepare' NPZ too) or 'default' (the "
               "embedded synthetic flight); FILE:t0-t1 keeps t0 <= t <= t1 s of it (either end may be left out)")
"""What every flight option's help says after the flight's role."""


class _OneFlight(argparse.Action):
    """Store the one flight an option names; a second one is an error rather than silently the one kept."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        if getattr(namespace, self.dest, None) is not None:
            raise argparse.ArgumentError(self, "names one flight; given twice")
        setattr(namespace, self.dest, values)


class OldForm(argparse.Action):
    """A deprecated way of giving an option, left out of ``--help``: its value waits under its own name until the
    whole command line is read, then :func:`adopt_old_forms` hands it to ``adopt``, which writes it where the new
    form puts it. ``old`` and ``new`` name the two forms in the note (``{prog}`` in ``old``: the command)."""

    def __init__(self, option_strings: Sequence[str], dest: str, *, old: str, new: str,
                 adopt: Callable[[argparse.Namespace, str], None], **kwargs: Any) -> None:
        super().__init__(option_strings, dest, **{**kwargs, "default": argparse.SUPPRESS, "help": argparse.SUPPRESS})
        self.old, self.new, self.adopt = old, new, adopt

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        setattr(namespace, self.dest, values)


def adopt_old_forms(parser: argparse.ArgumentParser, namespace: argparse.Namespace) -> None:
    """Rewrite each old form on ``parser``'s command line (:class:`OldForm`) as its new form in ``namespace``, in
    the order the parser defines them, with one line on stderr per form: ``PROG: note: 'OLD' is deprecated; use
    NEW``. A value the new form cannot take is an error of the parser. The ``jaxheli`` parser calls it once its
    sub-command's arguments are parsed."""
    for action in parser._actions:
        if isinstance(action, OldForm) and action.dest in vars(namespace):
            old = action.old.format(prog=parser.prog)
            try:
                action.adopt(namespace, vars(namespace).pop(action.dest))
            except ValueError as err:
                parser.error(f"{old}: {err}")
            print(f"{parser.prog}: note: '{old}' is deprecated; use {action.new}", file=sys.stderr)


def adopt_as_data(namespace: argparse.Namespace, spec: str) -> None:
    """An old form's flight as ``--data`` (:class:`OldForm`'s ``adopt``); ``ValueError`` when both name one."""
    if namespace.data is not None:
        raise ValueError(f"give the flight once, as --data (not also {spec!r})")
    namespace.data = spec


def add_data_option(p: Options, role: str, *, aliases: Sequence[str] = (), several: bool = False,
                    required: bool = False, positional_form: bool = False) -> None:
    """Add ``--data FILE[:t0-t1]``, the flights a command reads, with ``role`` (what they are for) before the
    common help. ``several``: one or more after each ``--data``, which may be repeated (a list, ``None`` when
    absent); else one flight, given once (``None`` when absent). ``aliases``: other names of the same option
    (e.g. ``--train``). ``positional_form``: the command once took the flight as a positional ``FILE``, still
    read (then ``--data`` or ``FILE`` is required, not both) with a deprecation note."""
    kind = {"nargs": "+", "action": "extend"} if several else {"action": _OneFlight}
    text = f"{role}: {FLIGHT_HELP}" + ("; several: list them after --data, or repeat it" if several else "")
    group = p.add_mutually_exclusive_group(required=True) if positional_form else p
    group.add_argument("--data", *aliases, dest="data", default=None, required=required and not positional_form,
                       metavar=FLIGHT, help=text + (" (required)" if required else ""), **kind)
    if positional_form:
        group.add_argument("old_file", nargs="?", metavar="FILE", action=OldForm, old="{prog} FILE",
                           new="--data FILE", adopt=adopt_as_data)


def add_flight_option(p: Options, name: str, role: str, *, required: bool = False) -> None:
    """Add an option ``name FILE[:t0-t1]`` for one flight in a role of its own (e.g. ``--validate``), read like
    ``--data``."""
    p.add_argument(name, default=None, required=required, action=_OneFlight, metavar=FLIGHT,
                   help=f"{role}: {FLIGHT_HELP}" + (" (required)" if required else ""))


def add_load_options(p: Options) -> None:
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


def add_quiet_option(p: Options) -> None:
    """Add ``--quiet`` to the parser of a long-running command: without it, the command writes a progress line to
    stderr at each stage and whenever a stage runs long (:func:`jaxheli._progress.reporting`)."""
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


_HOLD_HELP = {
    "zoh": (("zoh", "foh"), "zoh", "input hold between samples (default zoh)"),
    "auto": (("auto", "zoh", "foh"), "auto", "input hold between samples: auto (default: foh where the training "
                                             "flights' sticks were low-passed, by jaxheli prepare --lowpass, zoh "
                                             "otherwise), zoh or foh"),
    "model": (("zoh", "foh"), None, "input hold between samples (default: the one a result.json was fitted with, "
                                    "else zoh)"),
}


def add_sim_options(p: Options, hold: str = "zoh") -> None:
    """Add ``--outputs``, ``--hold``, ``--g`` and ``--segment`` to the parser of a command that simulates; ``hold``
    names ``--hold``'s default: ``"zoh"``, ``"auto"`` (:func:`jaxheli.identify`'s choice by the flights) or
    ``"model"`` (the model file's own, :func:`jaxheli.evaluate.recorded_hold`)."""
    choices, default, text = _HOLD_HELP[hold]
    p.add_argument("--outputs", default=None, help="comma-separated channels, e.g. p,q,phi,theta (default: all measured)")
    p.add_argument("--hold", choices=choices, default=default, help=text)
    p.add_argument("--g", type=float, default=9.81, help="gravity, m/s^2 (default 9.81)")
    p.add_argument("--segment", type=float, default=None,
                   help="restart from measured states every SECONDS (multiple shooting); default: one long run")


def sim_options(args: argparse.Namespace) -> dict:
    """``hold`` (left out when not given and the model's own applies), ``g`` and ``segment`` as keyword arguments of
    the simulator (:func:`jaxheli.make_simulator`)."""
    return {"g": args.g, "segment": args.segment} | ({} if args.hold is None else {"hold": args.hold})


def fit_step(text: str) -> float | str:
    """A fit step option's value (``identify --fit-dt``, ``bench --model-fit-dt``): ``auto``, ``full`` or a positive step in seconds."""
    if text in ("auto", "full"):
        return text
    try:
        step = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'auto', 'full' or seconds, got {text!r}") from None
    if not step > 0.0:
        raise argparse.ArgumentTypeError(f"a step must be positive, got {text!r}")
    return step


def outputs(text: str | None) -> tuple[str, ...] | None:
    """The channels of a comma-separated ``--outputs`` value; ``None`` (the library's default) when not given."""
    return None if not text else tuple(c.strip() for c in text.split(",") if c.strip())
