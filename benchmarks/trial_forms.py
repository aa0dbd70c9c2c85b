"""How close each candidate alone comes to a blind trial's noise-free effect::

    python benchmarks/trial_forms.py servo_dynamics:61 logger_delay:0 [...] [--candidates actuator_lag input_delay]

For each ``KIND:SEED`` of the independent simulator's blind check (wide truths: the scenario and the draw of
``jaxheli blind --truth independent --truths wide``), the trial's training flight is flown noise-free with its
effect and predicted as the diagnosis predicts a flight, by the truth's own 40 parameters with one candidate fitted
alone (:func:`jaxheli.benchmark.forms.form_gap`). Printed per trial: the effect's size and each candidate's
residual in sensor-noise std, with the candidate's fitted values. The truth is handed in: a probe of the candidates'
forms, not a score of the diagnosis.
"""

import argparse
import json

import jax

jax.config.update("jax_enable_x64", True)

from jaxheli._progress import reporting, stage  # noqa: E402
from jaxheli.benchmark import truth  # noqa: E402
from jaxheli.benchmark.blind import scenario  # noqa: E402
from jaxheli.benchmark.forms import form_gap  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("trials", nargs="+", help="KIND:SEED, e.g. servo_dynamics:61")
    p.add_argument("--candidates", nargs="+", default=["actuator_lag", "input_delay"])
    p.add_argument("--duration", type=float, default=30.0)
    p.add_argument("--dt", type=float, default=0.05)
    a = p.parse_args()
    with reporting():
        for spec in a.trials:
            kind, seed = spec.split(":")
            where = scenario(int(seed), "wide")
            trial = truth.truth_trial(kind, int(seed), where.theta, style=where.style, noise=where.noise,
                                      strength=where.strength, duration=a.duration, dt=a.dt)
            row: dict = {"resolvable": trial.resolvable}
            for name in a.candidates:
                with stage(f"{kind} {seed}: {name} fitted alone to the noise-free effect") as now:
                    gap = form_gap(where.theta, trial.injected.effects, (name,), style=where.style,
                                   seed=2 * int(seed), duration=a.duration, dt=a.dt, noise=where.noise)
                    now.outcome = f"residual {gap.residual:.3f} sensor-noise std"
                row["size"] = round(gap.size, 3)
                row[name] = {"residual": round(gap.residual, 3),
                             "values": {k: round(v, 4) for k, v in gap.values.items() if abs(v) > 1e-3}}
            print(f"{kind} {seed}: {json.dumps(row)}", flush=True)


if __name__ == "__main__":
    main()
