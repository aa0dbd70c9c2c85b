"""The fit at a coarser step on a synthetic low-passed flight: how much the step and the input hold cost::

    python benchmarks/fit_step.py [--seeds 4] [--steps 0.02 0.04] [--holds zoh foh] --out F.json

A 30-s piloted flight of the Table 2 truth at 0.01 s (mixed excitation, 0.2-2.5 Hz, sensor noise 1x; each of
``--seeds`` draws the sensor noise, the sticks are the same), inputs and outputs low-passed at 3 Hz as flight A is
prepared. PEM (200 steps, from 10 % off the truth) fits it at its own step with each of ``--holds``, and resampled to
each of ``--steps`` with each; every model is scored on the record at its own step (5-s runs from measured states,
PEM's training scores: in-sample) with a zero-order hold and with the hold it was fitted with, and its parameters are
compared with the full-rate fit of the first hold and with the full-rate fit of its own hold, each in that fit's
Cramer-Rao standard errors.

With several seeds the parameters are also compared in the estimator's own standard deviation: for each hold, the
spread (sample standard deviation over the seeds) of its full-rate fits, and for each coarse row the root mean square
over the seeds of its difference from the same seed's full-rate fit of its hold, per parameter, in that spread (the
step's error against the noise's), beside the Cramer-Rao standard errors' median ratio to that spread. Prints tables
and writes them as JSON.
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
    parser.add_argument("--seeds", type=int, nargs="+", default=[4], help="noise seeds, one flight each")
    parser.add_argument("--steps", type=float, nargs="+", default=[0.02, 0.04])
    parser.add_argument("--holds", nargs="+", choices=("zoh", "foh"), default=["zoh", "foh"])
    parser.add_argument("--out", default="fit_step.json")
    args = parser.parse_args()
    configure_xla()
    warnings.simplefilter("ignore", UserWarning)  # PEM's step-limit warning: the rows record convergence
    flights = {seed: _flight(seed, args.steps, args.holds) for seed in args.seeds}
    out = {"seeds": args.seeds, "flights": [{"seed": s, "rows": f["rows"]} for s, f in flights.items()]}
    if len(args.seeds) > 1:
        out["spread"] = _spread(flights, args.steps, args.holds)
    with open(args.out, "w") as f:
        json.dump(out, f, indent=1)


def _flight(seed: int, steps: list[float], holds: list[str]) -> dict:
    """Every fit of one noise seed's flight: its rows and its fits' parameters and standard errors."""
    flight = piloted_flight(duration=30.0, dt=0.01, excitation=Excitation("mixed", band=(0.2, 2.5)), seed=seed)
    flight = lowpass(flight, 3.0)
    start = np.where(np.asarray(TABLE2) != 0.0, 1.1 * np.asarray(TABLE2), 0.0)
    scored = make_problem(flight).variant(segment=5.0, x0="measured")
    full, fits, rows = {}, {}, []
    for step, hold in [(flight.dt, h) for h in holds] + [(s, h) for s in steps for h in holds]:
        fit = identify(flight if step == flight.dt else resample(flight, step), method="pem", start=start, hold=hold,
                       fit_dt="full")
        full.setdefault(hold, fit)
        fits[(step, hold)] = fit
        fitted = scores(fit.params, scored.variant(hold="zoh"))["fit_percent"]
        own = scores(fit.params, scored.variant(hold=hold))["fit_percent"]
        distance = {ref: _distance(fit, full[ref]) for ref in (holds[0], hold)}
        rows.append({"step_s": step, "hold": hold, "converged": fit.convergence["converged"],
                     "fit_percent": {c: fitted[c] for c in CHANNELS},
                     "fit_percent_own_hold": {c: own[c] for c in CHANNELS},
                     "se_from_full": distance[holds[0]], "se_from_full_same_hold": distance[hold]})
        print(f"seed {seed} {step:.3g} s {hold}: fit % (zoh scored) "
              + " ".join(f"{c} {fitted[c]:.1f}" for c in CHANNELS)
              + " | own hold " + " ".join(f"{c} {own[c]:.1f}" for c in CHANNELS)
              + f"; parameters from the full-rate {holds[0]} / same-hold fit: median "
              + " / ".join(f"{distance[r]['median']:.2f}" for r in (holds[0], hold)) + ", max "
              + " / ".join(f"{distance[r]['max']:.2f}" for r in (holds[0], hold)) + " standard errors", flush=True)
    return {"rows": rows, "dt": flight.dt, "fits": fits}


def _distance(fit, reference) -> dict:
    """``|fit - reference|`` over the reference's resolved parameters, in its Cramer-Rao standard errors: median,
    max and the number resolved."""
    stderr = _stderr(reference)
    resolved = np.isfinite(stderr) & (stderr > 0.0)
    z = np.abs(fit.params - reference.params)[resolved] / stderr[resolved]
    return {"median": float(np.median(z)), "max": float(z.max()), "resolved": int(resolved.sum())}


def _stderr(fit) -> np.ndarray:
    return np.array([fit.stderr[n] for n in PARAM_NAMES])


def _spread(flights: dict, steps: list[float], holds: list[str]) -> dict:
    """Per hold: the full-rate fits' spread over the seeds and each coarse step's error in it (see the module)."""
    found = {}
    for hold in holds:
        full = np.stack([f["fits"][(f["dt"], hold)].params for f in flights.values()])
        sd = full.std(axis=0, ddof=1)
        stderr = np.stack([_stderr(f["fits"][(f["dt"], hold)]) for f in flights.values()])
        moving = sd > 0.0
        resolved = moving & np.all(np.isfinite(stderr) & (stderr > 0.0), axis=0)
        ratio = float(np.median(np.median(stderr, axis=0)[resolved] / sd[resolved]))
        entry = {"parameters": int(moving.sum()), "cramer_rao_over_spread_median": ratio, "steps": {}}
        print(f"{hold}: {int(moving.sum())} parameters move between seeds; Cramer-Rao standard error / spread: "
              f"median {ratio:.2f}")
        for step in steps:
            coarse = np.stack([f["fits"][(step, hold)].params for f in flights.values()])
            rms = np.sqrt(np.mean((coarse - full) ** 2, axis=0))[moving] / sd[moving]
            names = [n for n, m in zip(PARAM_NAMES, moving) if m]
            worst = sorted(zip(rms, names), reverse=True)[:5]
            entry["steps"][f"{step:g}"] = {"rms_over_spread": dict(zip(names, map(float, rms))),
                                           "median": float(np.median(rms)), "max": float(rms.max()),
                                           "within_one": int(np.sum(rms <= 1.0))}
            print(f"  {step:g} s: step's error / spread median {np.median(rms):.2f}, max {rms.max():.2f}; "
                  f"{int(np.sum(rms <= 1.0))} of {rms.size} within one; largest "
                  + ", ".join(f"{n} {r:.2f}" for r, n in worst), flush=True)
        found[hold] = entry
    return found


if __name__ == "__main__":
    main()
