"""Blind records graded again by the verdict's rules as they are now, without flying a seed::

    python benchmarks/blind_regrade.py OUT/blind.json [OUT2/blind.json ...]

Each trial of each ``blind.json`` (``jaxheli blind --out OUT``; gzipped too, as the test looks' records in
``benchmarks/looks/`` are kept) is graded by
:func:`jaxheli.benchmark.blind.regrade` on the fits the record kept (ranking, base re-fit, structure, re-checks).
Printed: every trial whose named effect changes, then per kind the top-1 of the resolvable trials as recorded and as
graded now. The fits are those of the code that flew the seeds; only the rules that read them are today's.
"""

import argparse
import gzip
import json
from collections import defaultdict

import jax

jax.config.update("jax_enable_x64", True)

from jaxheli.benchmark.blind import regraded_top  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("records", nargs="+", help="blind.json files written by `jaxheli blind --out` (or gzipped)")
    args = parser.parse_args()
    tally: dict[str, list[int]] = defaultdict(lambda: [0, 0, 0])
    for path in args.records:
        with (gzip.open if path.endswith(".gz") else open)(path, "rt") as f:
            records = json.load(f)["records"]
        for r in records:
            now, right = regraded_top(r), r.get("right", [r["kind"]])  # the library simulator's kinds name themselves
            if now != r["top"]:
                print(f"{path}: {r['kind']} seed {r['seed']}{'' if r['resolvable'] else ' (not resolvable)'}: "
                      f"{r['top']} ({'right' if r['correct'] else 'wrong'}) -> {now} "
                      f"({'right' if now in right else 'wrong'})")
            if r["resolvable"] or r["kind"] == "none":
                row = tally[r["kind"]]
                row[0] += 1
                row[1] += bool(r["correct"])
                row[2] += now in right
    print("\n| kind | resolvable (controls: all) | top-1 as recorded | top-1 graded now |\n|---|---|---|---|")
    for kind, (n, before, after) in sorted(tally.items()):
        print(f"| {kind} | {n} | {before} | {after} |")


if __name__ == "__main__":
    main()
