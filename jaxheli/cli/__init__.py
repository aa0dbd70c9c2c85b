"""Command line: ``jaxheli prepare | identify | evaluate | verify | synth | check | localise | diagnose | blind | bench |
trials-scaling | report`` (``jaxheli COMMAND --help``).

Each module registers the parsers of one command group and holds their handlers, which parse arguments, call
the library and print or write: :mod:`~jaxheli.cli.prepare` (prepare), :mod:`~jaxheli.cli.identify` (identify,
evaluate, synth), :mod:`~jaxheli.cli.verify` (verify), :mod:`~jaxheli.cli.gap` (check, localise, diagnose, blind), :mod:`~jaxheli.cli.bench` (bench,
trials-scaling), :mod:`~jaxheli.cli.report` (report); :mod:`~jaxheli.cli._options` holds the options several
commands share; the commands with ``--quiet`` write progress lines to stderr unless it is given.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import NoReturn, TextIO

from .._compile_cache import use_compile_cache
from .._xla import configure_xla
from .._progress import reporting
from ._options import adopt_old_forms
from .bench import add_bench_parser, add_trials_scaling_parser
from .gap import add_blind_parser, add_check_parser, add_diagnose_parser, add_localise_parser
from .identify import add_evaluate_parser, add_identify_parser, add_synth_parser
from .prepare import add_prepare_parser
from .report import add_report_parser
from .verify import add_verify_parser


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line and a pointer to ``--help``, without the usage text, and which
    reads the deprecated forms of its options as their new ones (:func:`~jaxheli.cli._options.adopt_old_forms`)."""

    def parse_known_args(self, args: Sequence[str] | None = None,
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        namespace, extras = super().parse_known_args(args, namespace)
        adopt_old_forms(self, namespace)
        return namespace, extras

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\nsee {self.prog} --help\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``jaxheli`` argument parser (all sub-commands)."""
    parser = _Parser(
        prog="jaxheli",
        description="System identification of small unmanned helicopters (Mettler's 13-state hover model) in JAX.",
    )
    parser.add_argument("--float32", action="store_true", help="compute in float32 (faster; default float64)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for add in (add_prepare_parser, add_identify_parser, add_evaluate_parser, add_verify_parser, add_synth_parser,
                add_check_parser,
                add_localise_parser, add_diagnose_parser, add_blind_parser, add_bench_parser, add_trials_scaling_parser,
                add_report_parser):
        add(sub)
    return parser


_TIMES_COMPILATION = frozenset({"bench", "trials-scaling"})
"""Commands whose timings include compilation: they compile afresh (:mod:`jaxheli._compile_cache`)."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxheli`` command."""
    configure_xla()  # XLA_FLAGS, before JAX's backend starts (the imports above do not start it)
    args = build_parser().parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", not args.float32)
    if args.command not in _TIMES_COMPILATION:
        use_compile_cache()
    with _console_warnings(f"jaxheli {args.command}"), reporting(getattr(args, "quiet", True) is False):
        try:
            return args.func(args)
        except (FileNotFoundError, ValueError) as err:
            print(f"jaxheli {args.command}: error: {err}", file=sys.stderr)
            return 2


@contextmanager
def _console_warnings(prog: str) -> Iterator[None]:
    """Within the block, each warning the filters let through reaches stderr as one plain line
    ``PROG: warning: MESSAGE`` (no source path or code line), a message repeated from anywhere only once; the
    previous display comes back after it."""
    shown: set[str] = set()

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: TextIO | None = None, line: str | None = None) -> None:
        text = " ".join(str(message).split())
        if text not in shown:
            shown.add(text)
            print(f"{prog}: warning: {text}", file=sys.stderr if file is None else file)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield
