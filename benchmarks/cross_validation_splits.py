"""Held-out evidence for the output-error polish's leave-one-window-out cross-validation on flight A's time splits.

Flight A (prepared as ``benchmarks/identification.py`` does) is split in time four ways (first 60 % / last 40 %,
last 60 % / first 40 %, first and last halves each way); the default recipe identifies every training part with
the polish's full schedule and with its run length and stopping round chosen by cross-validation over 3 windows
(``identify(cv_windows=3)``), and each model, and the paper's Table 2 model, is verified on the held-out part and
on flight C: Pearson and fit % per channel (p, q, phi, theta) over 5-s runs, each from its least-squares start
with a per-channel bias (``jaxheli verify``). Counts how often the cross-validated model beats the full schedule's.

Usage::

    python benchmarks/cross_validation_splits.py [--iterations 100] [--windows 3] [--out results/cv_splits]

Writes ``rows.json`` and ``tables.md`` under ``--out`` after every model.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax

from identification import REAL_CHANNELS, RUN_S, real_flights
from jaxheli.data.preprocess import split
from jaxheli.identify import identify
from jaxheli.model import TABLE2
from jaxheli.verify import verify

METRICS = (("pearson", "r", ".3f"), ("fit_percent", "fit", ".1f"))


def _splits() -> tuple[list[tuple[str, object, str, object]], object]:
    """``(train label, train, held-out label, held-out)`` for each split of A, and flight C."""
    trains, validations = real_flights()
    a = trains["A"]
    first60, last40 = split(a, 0.6)
    first40, last60 = split(a, 0.4)
    first50, last50 = split(a, 0.5)
    return [("A first 60 %", first60, "A last 40 %", last40), ("A last 60 %", last60, "A first 40 %", first40),
            ("A first 50 %", first50, "A last 50 %", last50), ("A last 50 %", last50, "A first 50 %", first50)], \
        validations["C"]


def _score(theta, flight) -> dict:
    pooled = verify(theta, flight, run_length=RUN_S).pooled
    return {key: {c: float(pooled[key][c]) for c in REAL_CHANNELS} for key, _, _ in METRICS}


def _table(rows: list[dict]) -> str:
    head = " | ".join(f"{short} {c}" for _, short, _ in METRICS for c in REAL_CHANNELS)
    lines = ["| train | model | validate | s | " + head + " |", "|---" * (4 + 2 * len(REAL_CHANNELS)) + "|"]
    for r in rows:
        cells = " | ".join(f"{r[key][c]:{fmt}}" for key, _, fmt in METRICS for c in REAL_CHANNELS)
        lines.append(f"| {r['train']} | {r['model']} | {r['validate']} | {r['seconds']:.0f} | {cells} |")
    wins = {key: [0, 0] for key, _, _ in METRICS}
    for cv in (r for r in rows if r["model"].startswith("cv")):
        full = next(r for r in rows if r["train"] == cv["train"] and r["validate"] == cv["validate"]
                    and r["model"] == "full schedule")
        for key, _, _ in METRICS:
            wins[key][0] += sum(cv[key][c] > full[key][c] for c in REAL_CHANNELS)
            wins[key][1] += len(REAL_CHANNELS)
    lines += ["", "Cross-validated model above the full schedule's: " + ", ".join(
        f"{short} {w} of {n}" for (key, short, _), (w, n) in zip(METRICS, wins.values()))]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--iterations", type=int, default=100, help="IWO generations")
    parser.add_argument("--windows", type=int, default=3, help="cross-validation windows")
    parser.add_argument("--out", default="results/cv_splits")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cases, flight_c = _splits()
    rows = []
    for train_label, train, held_label, held in cases:
        rows.append({"train": "-", "model": "paper Table 2", "validate": held_label, "seconds": 0.0,
                     **_score(TABLE2, held)})
        for cv in (0, args.windows):
            t0 = time.perf_counter()
            res = identify(train, iterations=args.iterations, cv_windows=cv, progress=False)
            seconds = time.perf_counter() - t0
            chosen = res.polish.get("cross_validation")
            model = f"cv {cv}: {chosen['final_s']:.3g} s x {chosen['rounds']}" if cv else "full schedule"
            for label, flight in ((held_label, held), ("C", flight_c)):
                rows.append({"train": train_label, "model": model, "validate": label, "seconds": seconds,
                             **_score(res.params, flight)})
            (out / "rows.json").write_text(json.dumps(rows, indent=1))
            (out / "tables.md").write_text(_table(rows))
            print(f"{train_label} {model}: {seconds:.0f} s", flush=True)
    print(_table(rows))


if __name__ == "__main__":
    main()
