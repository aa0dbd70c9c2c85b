"""The fit at a coarser step on a synthetic low-passed flight: how much the step and the input hold cost::

    python benchmarks/fit_step.py [--seed 4] [--steps 0.02 0.04] --out F.json

A 30-s piloted flight of the Table 2 truth at 0.01 s (mixed excitation, 0.2-2.5 Hz, sensor noise 1x, ``--seed``),
inputs and outputs low-passed at 3 Hz as flight A is prepared. PEM (200 steps, from 10 % off the truth) fits it at its
own step with a zero- and a first-order hold, and resampled to each of ``--steps`` with both; every model is scored
on the record at its own step (5-s runs from measured states, PEM's training scores: in-sample) with a zero-order hold
and with the hold it was fitted with, and its parameters are compared with the full-rate zero-order fit's and with the
full-rate fit of its own hold, each in that fit's Cramer-Rao standard errors. Prints a table and writes it as JSON.
"""

import argparse
import json
import warnings

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from jaxheli import configure_xla, identify, make_problem, piloted_flight  # noqa: E402
from jaxheli.data.preprocess import lowpass, resample  # noqa: E402
from jaxheli.identify import scores  # noqa: E402
from jaxheli.model import PARAM_NAMES, TABLE2  # noqa: E402
from jaxheli.synth.excitation import Excitation  # noqa: E402

CHANNELS = ("u", "v", "p", "q", "phi", "theta", "w", "r")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=4)
    parser.add_argument("--steps", type=float, nargs="+", default=[0.02, 0.04])
    parser.add_argument("--out", default="fit_step.json")
    args = parser.parse_args()
    configure_xla()
    warnings.simplefilter("ignore", UserWarning)  # PEM's step-limit warning: the rows record convergence
    flight = piloted_flight(duration=30.0, dt=0.01, excitation=Excitation("mixed", band=(0.2, 2.5)), seed=args.seed)
    flight = lowpass(flight, 3.0)
    start = np.where(np.asarray(TABLE2) != 0.0, 1.1 * np.asarray(TABLE2), 0.0)
    scored = make_problem(flight).variant(segment=5.0, x0="measured")
    full = {}
    rows = []
    for step, hold in [(flight.dt, "zoh"), (flight.dt, "foh")] + [(s, h) for s in args.steps for h in ("zoh", "foh")]:
        fit = identify(flight if step == flight.dt else resample(flight, step), method="pem", start=start, hold=hold)
        full.setdefault(hold, fit)
        fitted = scores(fit.params, scored)["fit_percent"]
        own = fitted if hold == "zoh" else scores(fit.params, scored.variant(hold=hold))["fit_percent"]
        distance = {ref: _distance(fit, full[ref]) for ref in ("zoh", hold)}
        rows.append({"step_s": step, "hold": hold, "converged": fit.convergence["converged"],
                     "fit_percent": {c: fitted[c] for c in CHANNELS},
                     "fit_percent_own_hold": {c: own[c] for c in CHANNELS},
                     "se_from_full": distance["zoh"], "se_from_full_same_hold": distance[hold]})
        print(f"{step:.3g} s {hold}: fit % (zoh scored) " + " ".join(f"{c} {fitted[c]:.1f}" for c in CHANNELS)
              + " | own hold " + " ".join(f"{c} {own[c]:.1f}" for c in CHANNELS)
              + "; parameters from the full-rate zoh / same-hold fit: median "
              + " / ".join(f"{distance[r]['median']:.2f}" for r in ("zoh", hold)) + ", max "
              + " / ".join(f"{distance[r]['max']:.2f}" for r in ("zoh", hold)) + " standard errors", flush=True)
    with open(args.out, "w") as f:
        json.dump({"seed": args.seed, "rows": rows}, f, indent=1)


def _distance(fit, reference) -> dict:
    """``|fit - reference|`` over the reference's resolved parameters, in its Cramer-Rao standard errors: median,
    max and the number resolved."""
    stderr = np.array([reference.stderr[n] for n in PARAM_NAMES])
    resolved = np.isfinite(stderr) & (stderr > 0.0)
    z = np.abs(fit.params - reference.params)[resolved] / stderr[resolved]
    return {"median": float(np.median(z)), "max": float(z.max()), "resolved": int(resolved.sum())}


if __name__ == "__main__":
    main()
