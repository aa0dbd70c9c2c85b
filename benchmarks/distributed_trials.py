"""K IWO trials on one process vs several local ``jax.distributed`` processes (CPU, gloo)::

    python benchmarks/distributed_trials.py [--trials 10] [--iterations 50] [--samples 1000] [--processes 1 2]

The same as ``jaxheli trials-scaling`` once wired into the command line (:func:`jaxheli.distributed.trials_scaling`).
"""

import argparse
import sys

from jaxheli.cli.bench import add_trials_scaling_parser

if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="distributed_trials.py")
    add_trials_scaling_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["trials-scaling", *sys.argv[1:]])
    sys.exit(args.func(args))
