"""How far each kind of the independent truth simulator lies from its nearest candidate form::

    python benchmarks/truth_forms.py [--kinds ...] [--seeds 3] [--strength 1] [--duration 30] --out forms.json

For each kind (and the in-family controls of :func:`jaxheli.benchmark.forms.in_family`) and seed, the noise-free
effect on the Table 2 and R-50 truths is predicted as the diagnosis predicts a flight, with the nearest candidate
fitted alone (:func:`jaxheli.benchmark.forms.kind_gap`): its size and the residual left, in sensor-noise std.
A residual above 1 puts the kind outside every candidate's family. Writes JSON rows and prints a table.
"""

import argparse
import json
import platform
import subprocess
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from jaxheli.benchmark import truth  # noqa: E402
from jaxheli.benchmark.forms import form_gap, in_family, kind_gap  # noqa: E402
from jaxheli.model import R50_SI, TABLE2  # noqa: E402

TRUTHS = {"table2": TABLE2, "r50": R50_SI}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kinds", nargs="+", default=list(truth.SINGLE))
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--strength", type=float, default=1.0)
    p.add_argument("--duration", type=float, default=30.0)
    p.add_argument("--dt", type=float, default=0.05)
    p.add_argument("--style", default="sweep", help="the flight's excitation (jaxheli.benchmark.truth.excitation)")
    p.add_argument("--truths", nargs="+", default=list(TRUTHS), choices=list(TRUTHS))
    p.add_argument("--out", required=True)
    a = p.parse_args()
    rows = []
    t0 = time.perf_counter()
    for name, theta in ((t, TRUTHS[t]) for t in a.truths):
        for kind, (effects, candidates) in in_family(a.dt).items():
            g = form_gap(theta, effects, candidates, style=a.style, seed=0, duration=a.duration, dt=a.dt)
            rows.append({"truth": name, "kind": kind, "seed": 0, "row": "in-family control", **g.__dict__})
        for kind in a.kinds:
            for seed in range(a.seeds):
                g = kind_gap(kind, seed, theta, style=a.style, strength=a.strength, duration=a.duration, dt=a.dt)
                rows.append({"truth": name, "kind": kind, "seed": seed, "row": "other form", **g.__dict__})
        for r in rows[-(len(a.kinds) * a.seeds + 2):]:
            print(f"{r['truth']:7s} {r['kind']:18s} {r['seed']:2d} size {r['size']:7.2f} residual "
                  f"{r['residual']:6.2f} {r['nearest']}", flush=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    meta = {"command": "python benchmarks/truth_forms.py " + " ".join(
                f"--{k} {' '.join(map(str, v)) if isinstance(v, list) else v}" for k, v in vars(a).items()),
            "commit": commit, "machine": f"{platform.machine()}, {platform.processor() or 'cpu'}",
            "label": "measured, noise-free flights, design (no rule set on them)",
            "seconds": time.perf_counter() - t0}
    with open(a.out, "w") as f:
        json.dump({"meta": meta, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
