"""Issue 66's probe of a recipe that searches in the authors' box and widens only its polish::

    python benchmarks/widened_polish.py [--iterations 1000] --out F.json

Flight A as the project prepares it, and its first 60 % (``benchmarks/identification.py``'s ``real_flights``): the
default method (``iwo+freq+polish``, seed 0) in the authors' box, then that answer polished again (output error, 4
rounds of 100 steps) in the physical box (``model.WIDE_LOWER/UPPER``). Both models are scored on flight C and on A's
last 40 % (5-s runs from measured states, as the recipes table: held out unless the record was trained on). Prints
Pearson / fit % on p, q, phi, theta and writes every score as JSON.
"""

import argparse
import json
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from identification import _real_scores, _sample, real_flights  # noqa: E402
from jaxheli import configure_xla, identify  # noqa: E402
from jaxheli.bounds import named_box  # noqa: E402
from jaxheli.optim.polish import polish  # noqa: E402

SHOWN = ("p", "q", "phi", "theta")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=1000)
    parser.add_argument("--out", default="widened_polish.json")
    args = parser.parse_args()
    configure_xla()
    wide = named_box("wide")
    trains, validations = real_flights()
    rows = []
    for label, train in trains.items():
        t0 = time.perf_counter()
        default = np.asarray(identify(train, seed=0, iterations=args.iterations).params)
        t1 = time.perf_counter()
        widened = np.asarray(polish(default, train, objective="output-error", max_steps=100, rounds=4,
                                    lower=np.asarray(wide.lower), upper=np.asarray(wide.upper)).theta)
        seconds = {"default": t1 - t0, "widened": time.perf_counter() - t1}
        for recipe, params in (("default", default), ("default, polish widened", widened)):
            for where, flight in validations.items():
                runs = _real_scores(params, flight)["runs"]
                rows.append({"train": label, "recipe": recipe, "validate": where, "sample": _sample(label, where),
                             "seconds": seconds["default" if recipe == "default" else "widened"], "runs": runs,
                             "params": params.tolist()})
                print(f"{label} | {recipe} | {where} ({rows[-1]['sample']}): "
                      + " ".join(f"{runs['pearson'][c]:.3f}" for c in SHOWN) + " / "
                      + " ".join(f"{runs['fit_percent'][c]:.1f}" for c in SHOWN), flush=True)
    with open(args.out, "w") as f:
        json.dump({"command": "python benchmarks/widened_polish.py --iterations " + str(args.iterations),
                   "label": "measured; held out unless 'sample' says in-sample", "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
