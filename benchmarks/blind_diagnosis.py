"""Blind benchmark of the effect diagnosis: every effect kind plus the effect-free control, N seeds each.

Each trial's base model is identified by PEM on its contaminated training flight (never the truth), and on the
first ``--iwo-seeds`` seeds of every kind also by IWO + polish (reported beside PEM on the same trials); the
scenario (truth model, pilot style, noise, effect strength) cycles with the seed (:func:`jaxheli.benchmark.blind.
scenario`). Writes ``OUT/blind.json`` (per-trial records and the summary) and ``OUT/blind.md`` (per kind:
top-1 and in-tie-set % and median magnitude error over all, detectable and identifiable trials, the training
fit's and the oracle's magnitude error, median shrink vs the oracle; false-positive %), both after every trial.
Usage::

    python benchmarks/blind_diagnosis.py --refly-design [--seeds 20] [--iwo-seeds 3] [--kinds input_delay none ...] [--pem-steps 100] [--workers 2] [--out results/blind]

(every design seed is spent, so design runs fly them again with ``--refly-design``; the options are ``jaxheli blind``'s).
"""

from __future__ import annotations

import argparse
import sys

import jax

from jaxheli import configure_xla
from jaxheli.cli.gap import add_blind_parser


def main(argv: list[str] | None = None) -> int:
    configure_xla()  # before the trials' worker processes start: they inherit it
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
