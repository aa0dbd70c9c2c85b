"""Performance of the cost kernels; the same as ``jaxheli bench`` (see ``jaxheli bench --help``)::

    python benchmarks/bench.py [--sizes 40 400 4000] [--samples 1000 8590 40000] [--host-devices 2] [--out DIR]
"""

import sys

from jaxheli.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
