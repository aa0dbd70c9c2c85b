"""How much of a blind trial's effect could the effect-free model absorb? A post-hoc reading of a blind run::

    python benchmarks/absorption.py --records RUN/blind.json [--kinds drag servo_dynamics ...] --out absorption.json

The blind check calls a trial *detectable* when its effect moves some noise-free validation reading by more than the
sensor noise (``max_k rms_t(y_eff - y_clean) / sigma_k > 1``, the flights re-flown in closed loop with and without
it). That says the flight differs; it does not say that the difference is one the base model's own 40 parameters
cannot take up. Here, for each detectable trial of the records (either simulator, the same scenario and seeds), the
base model alone is fitted **in-sample to the noise-free validation flight itself** (PEM, 200 LM steps in the
blind check's hull box, then output error in 6-s runs each from its least-squares state, 150 steps: the diagnosis's
6-s segment restart re-estimated from the segment's readings), once with the effect (``y_eff``) and once to the
same flight re-flown without it (``y_clean``: the floor the two simulators' structural differences leave). Per
channel ``rms_k`` of the fit's output error over ``sigma_k``; the trial's

    excess = max_k sqrt(max(rms_eff,k^2 - rms_clean,k^2, 0))

is the part of the effect that the effect-free model class leaves even when fitted to the very flight it is scored on,
in sensor-noise units. ``excess <= 1``: fitted to the noise-free flight, the base model alone already comes within
the sensor noise of it: on that flight the effect is confounded with the base model's parameters, and a diagnosis
that credits an effect by its shrink of the validation gap beyond the base re-fitted alone can name it only where the
training flight pins those parameters otherwise. The fits use the library's PEM and output error, so this is a
diagnostic of where misses come from, never a subset to score on or a rule; the records' verdicts are not changed.
Writes one row per trial (the per-channel rms, ``excess`` and the trial's verdict) after each trial.
"""

import argparse
import json
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from jaxheli.benchmark.blind import BOXES, DEFAULT_OUTPUTS, noise_free_validation  # noqa: E402
from jaxheli.data.flight import FlightData  # noqa: E402
from jaxheli.optim.pem import fit, fitted_problem, pem  # noqa: E402

SEGMENT_S = 6.0
"""Run length, s, of the in-sample output-error fit (the diagnosis's restart interval)."""


def in_sample_rms(time_s: np.ndarray, sticks: np.ndarray, readings: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Per channel rms of the base model's output error, over ``sigma``, when fitted to the noise-free ``readings``
    [N, k] (channels :data:`DEFAULT_OUTPUTS`) themselves: PEM, then output error in :data:`SEGMENT_S` runs."""
    flight = FlightData(time_s, sticks, readings, DEFAULT_OUTPUTS, source="noise-free validation flight")
    lower, upper = BOXES["hull"]
    base = pem(flight, max_steps=200, outputs=DEFAULT_OUTPUTS, lower=lower, upper=upper)
    runs = fitted_problem(flight, outputs=DEFAULT_OUTPUTS, lower=lower, upper=upper).variant(
        segment=SEGMENT_S, x0="estimated", simulator="scan")
    res = fit(runs, base.theta, "pem", "lm", 150, None, 1e-8, 1e-8)
    y = np.asarray(runs.sim(np.asarray(res.theta)))
    return np.sqrt(np.mean((y - readings) ** 2, axis=0)) / sigma


def absorption(record: dict) -> dict:
    """The in-sample rms with and without the effect and the ``excess`` (module docstring) of one blind record."""
    seed, kind = int(record["seed"]), record["kind"]
    flown, bare, sigma = noise_free_validation(record["truth_sim"], kind, seed)  # as the blind check flew them
    with_effect, without = in_sample_rms(*flown, sigma), in_sample_rms(*bare, sigma)
    excess = np.sqrt(np.maximum(with_effect**2 - without**2, 0.0))
    return {"kind": kind, "seed": seed, "parts": record.get("parts"), "top": record["top"],
            "correct": record["correct"], "detectability": record["detectability"],
            "resolvable": record.get("resolvable"), "oracle_shrink_pct": record.get("oracle_shrink_pct"),
            "rms_effect": dict(zip(DEFAULT_OUTPUTS, with_effect.tolist())),
            "rms_clean": dict(zip(DEFAULT_OUTPUTS, without.tolist())),
            "excess": float(excess.max()), "excess_channel": DEFAULT_OUTPUTS[int(excess.argmax())]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--records", required=True, help="blind.json of a blind run")
    p.add_argument("--kinds", nargs="+", help="kinds to read (default: every kind with a candidate)")
    p.add_argument("--out", required=True, help="JSON file of the rows, rewritten after each trial")
    args = p.parse_args()
    records = json.load(open(args.records))["records"]
    chosen = [r for r in records if r["detectable"] and r["kind"] not in ("none", "quantisation", "vibration")
              and (args.kinds is None or r["kind"] in args.kinds)]
    rows = []
    for i, record in enumerate(chosen):
        start = time.perf_counter()
        rows.append(absorption(record))
        row = rows[-1]
        print(f"[{i + 1}/{len(chosen)}] {row['kind']} {row['seed']}: excess {row['excess']:.2f} "
              f"({row['excess_channel']}), {'right' if row['correct'] else row['top']} "
              f"({time.perf_counter() - start:.0f} s)", flush=True)
        with open(args.out, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
