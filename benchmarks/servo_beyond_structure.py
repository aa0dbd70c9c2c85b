"""A one-axis servo beyond a wrong base model: does any candidate explain it once the structure is freed? Design only::

    python benchmarks/servo_beyond_structure.py --seed 33 [--wn 12.5] [--zeta 1] [--axis lon] [--base default] \\
        --out F.json

The independent truth simulator flies the wide-class truth of blind design seed ``--seed``
(:func:`jaxheli.benchmark.blind.scenario`, ``wide``: couplings outside the authors' box) with a second-order servo
of natural frequency ``--wn`` (rad/s) and damping ``--zeta`` on one axis and no other effect: a 30-s sweep to train
on, the blind check's 3-2-1-1 to validate on (seeds ``2 seed`` and ``2 seed + 1``), sensor noise 1x. The base model
is identified on the training flight in the authors' box by ``--base`` (as ``jaxheli blind --base``); the staged
diagnosis (:func:`jaxheli.gap.ranking.staged`) ranks every candidate in that box, re-fits the base in the physical
ranges (the structure hypothesis) and re-checks the effects significant in the box beyond it. Here every candidate
is also ranked again from the structure's re-fit in the physical ranges, significant or not in the box: the shrink
an effect would be credited beyond the structure, which tells whether a rule naming effects there could name the
servo at all. Flights are not drawn through ``jaxheli blind`` and the seed ledger: design seeds only (0-99).
Writes the rankings, the structure and the verdict as JSON.
"""

import argparse
import json
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from jaxheli import configure_xla  # noqa: E402
from jaxheli._progress import reporting, stage  # noqa: E402
from jaxheli.benchmark.blind import BOXES, base_model, scenario  # noqa: E402
from jaxheli.benchmark.truth import NOISE, OUTPUTS, Effects, Servo, detectability_ratio, fly, outside_box  # noqa: E402
from jaxheli.bounds import Bounds, physical_box  # noqa: E402
from jaxheli.data.flight import FlightData  # noqa: E402
from jaxheli.effects import registry as fx  # noqa: E402
from jaxheli.gap.candidates import ranked  # noqa: E402
from jaxheli.gap.fit_effect import MAX_STEPS  # noqa: E402
from jaxheli.gap.ranking import predictor_pair, staged  # noqa: E402
from jaxheli.gap.reference import theta_box  # noqa: E402
from jaxheli.gap.significance import MIN_SHRINK  # noqa: E402
from jaxheli.gap.verdict import find  # noqa: E402

AXES = ("lat", "lon", "ped", "col")


def _rows(entries) -> list[dict]:
    return [{"effect": e.effect, "shrink_pct": e.shrink_pct, "shrink_se_pct": e.shrink_se_pct,
             "significant": e.significant, "fitted": e.fitted.summary} for e in entries]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, required=True, help="a blind design seed (0-99): the wide truth and flights")
    p.add_argument("--wn", type=float, default=12.5, help="servo natural frequency, rad/s")
    p.add_argument("--zeta", type=float, default=1.0, help="servo damping ratio")
    p.add_argument("--axis", choices=AXES, default="lon")
    p.add_argument("--base", choices=("pem", "iwo+polish", "default"), default="default")
    p.add_argument("--out", required=True)
    a = p.parse_args()
    if not 0 <= a.seed <= 99:
        p.error("--seed: design seeds only (0-99)")
    configure_xla()
    where = scenario(a.seed, "wide")
    sigma = np.array([NOISE[c] for c in OUTPUTS])
    on = [i == AXES.index(a.axis) for i in range(len(AXES))]
    servo = Servo(wn=tuple(a.wn if o else np.inf for o in on), zeta=tuple(a.zeta if o else 0.7 for o in on))
    common = dict(duration=30.0, dt=0.05, noise=sigma, outputs=OUTPUTS)
    train = fly(where.theta, Effects(servo=servo), style="sweep", seed=2 * a.seed, **common)
    validate = fly(where.theta, Effects(servo=servo), style="validate", seed=2 * a.seed + 1, **common)
    clean = fly(where.theta, Effects(), style="validate", seed=2 * a.seed + 1, **common)
    flights = [FlightData(r.time, r.sticks, r.measured, tuple(OUTPUTS), source=f"design seed {a.seed} {role}")
               for r, role in ((train, "train"), (validate, "validate"))]
    with reporting():
        start = time.perf_counter()
        with stage(f"base model by {a.base} on the training flight, in the authors' box"):
            theta, ident = base_model(flights[0], a.base, a.seed, outputs=tuple(OUTPUTS), box="authors")
        base_s = time.perf_counter() - start
        tp, vp = predictor_pair(theta, *flights, segment=6.0, smooth=True)
        *arrays, owner = fx.tried_arrays(fx.ALL, tuple(OUTPUTS))
        box = Bounds(*BOXES["authors"])
        st = staged(tp, vp, theta, list(fx.ALL), tuple(arrays), owner, MAX_STEPS, MIN_SHRINK, theta_box(theta, box))
        s = st.structure
        beyond = []
        if s is not None and s.significant:
            with stage("every candidate ranked again beyond the structure, in the physical ranges"):
                beyond = ranked(tp, vp, s.theta, list(fx.ALL), tuple(arrays), owner, MAX_STEPS, MIN_SHRINK,
                                theta_box(s.theta, physical_box(box))).entries
    record = {
        "seed": a.seed, "truth": where.truth, "outside_box": list(outside_box(where.theta)), "axis": a.axis,
        "wn": a.wn, "zeta": a.zeta, "equivalent_lag_s": 2 * a.zeta / a.wn,
        "detectability": detectability_ratio(validate.clean, clean.clean, sigma),
        "base": {**ident, "seconds": base_s},
        "box": _rows(st.ranked.entries), "recheck": _rows(st.recheck), "beyond_structure": _rows(beyond),
        "structure": None if s is None else {"shrink_pct": s.shrink_pct, "shrink_se_pct": s.shrink_se_pct,
                                             "significant": s.significant, "summary": s.summary},
        "refit": None if st.refit is None else {"shrink_pct": st.refit.shrink_pct,
                                                "under_fitted": st.refit.under_fitted},
        "verdict": str(find(st.ranked.entries, st.refit, s, st.recheck)),
    }
    with open(a.out, "w") as f:
        json.dump(record, f, indent=1, default=float)
    for name in ("box", "beyond_structure"):
        for row in record[name]:
            print(f"{name:17s} {row['effect']:22s} {row['shrink_pct']:6.1f} +- {row['shrink_se_pct']:4.1f} "
                  f"{'significant' if row['significant'] else ''}")
    print("verdict:", record["verdict"])


if __name__ == "__main__":
    main()
