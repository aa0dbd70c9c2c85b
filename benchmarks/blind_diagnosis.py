"""Blind benchmark of the effect diagnosis: every effect kind plus the effect-free control, N seeds each.

Writes ``OUT/blind.json`` (per-trial records and the summary) and ``OUT/blind.md`` (the table: top-1
attribution %, median magnitude error, median shrink vs the oracle per kind, false-positive %). Usage::

    python benchmarks/blind_diagnosis.py [--seeds 20] [--kinds input_delay none ...] [--out results/blind]

The default (2 seeds) fits a 2-core box; the Done-when of issue 4 asks ``--seeds 20``.
"""

from __future__ import annotations

import argparse
import sys

import jax

from jaxheli.cli.gap import add_blind_parser


def main(argv: list[str] | None = None) -> int:
    jax.config.update("jax_enable_x64", True)
    parser = argparse.ArgumentParser(prog="blind_diagnosis", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command")
    add_blind_parser(sub)
    args = parser.parse_args(["blind", *(sys.argv[1:] if argv is None else argv)])
    if args.out == "jaxheli-blind":
        args.out = "results/blind"
    return args.func(args)


if __name__ == "__main__":
    raise SystemExit(main())
