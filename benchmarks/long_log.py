"""Logs of any length: a synthetic flight of 5 and of 30 minutes at 250 Hz through load, check, identify and verify.

Each length gets a training and a validation flight (Table 2 truth, piloted, every axis excited by the mixed
excitation, default sensor noise; seeds 1 and 2), written as NPZ like a converted log. Each step runs as the
command line runs it, in a fresh process of its own, timed by the wall clock with its peak resident memory
(``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` of a wrapper that runs nothing else):

- ``load``: :func:`jaxheli.load` of the training NPZ (reading and checking the record);
- ``check``: ``jaxheli check`` of the training flight (data consistency);
- ``identify``: ``jaxheli identify`` with the default method (IWO, the frequency fit, the polish), the settings below
  the same for every length;
- ``verify``: ``jaxheli verify`` of the identified model on the validation flight (5-s runs and one whole run).

The JSON holds each step's seconds and peak memory (MB) per length and the longest length's ratios to the shortest's:
the issue's test is peak memory under 8 GB and time within 8x the 5-minute flight's for a 6x longer record.

    python benchmarks/long_log.py --out /tmp/long-log            # writes /tmp/long-log/long_log.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

RATE_HZ = 250.0
MINUTES = (5.0, 30.0)
IDENTIFY = ("--iterations", "100", "--trials", "1", "--polish-steps", "20", "--polish-rounds", "2")
"""``jaxheli identify`` settings for every length (default method and box): the main job's 100 generations, one trial,
two polish rounds of 20 steps; what changes between the lengths is the record alone."""

_FLY = """
import sys
import jax
jax.config.update("jax_enable_x64", True)
import jaxheli
from jaxheli.synth.excitation import Excitation
seconds, dt, seed, out = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
flight = jaxheli.piloted_flight(jaxheli.TABLE2, duration=seconds, dt=dt, seed=seed,
                                excitation=Excitation("mixed", amplitude=(0.2,) * 4, unit=0.5, band=(0.2, 4.0)))
jaxheli.save_npz(flight.replace(source=f"synthetic {seconds:g} s at {1 / dt:g} Hz, seed {seed}"), out)
"""
_LOAD = "import sys, jaxheli; print(jaxheli.load(sys.argv[1]).n_samples)"
_MEASURED = """
import json, resource, subprocess, sys, time
start = time.perf_counter()
code = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL).returncode
print(json.dumps({"returncode": code, "seconds": time.perf_counter() - start,
                  "peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}))
"""
"""Runs one command and reports its wall time and peak resident memory (Linux: ``ru_maxrss`` in kB)."""


def measured(command: list[str]) -> dict:
    """``command`` in a fresh process: its return code, wall seconds and peak resident memory (MB)."""
    out = subprocess.run([sys.executable, "-c", _MEASURED, *command], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def one_length(minutes: float, rate: float, folder: Path) -> dict:
    """The four steps on a ``minutes``-long flight pair sampled at ``rate`` Hz, written under ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    train, validate = folder / "train.npz", folder / "validate.npz"
    for seed, path in ((1, train), (2, validate)):
        subprocess.run([sys.executable, "-c", _FLY, str(60.0 * minutes), str(1.0 / rate), str(seed), str(path)],
                       check=True)
    cli = [sys.executable, "-m", "jaxheli"]
    steps = {
        "load": [sys.executable, "-c", _LOAD, str(train)],
        "check": [*cli, "check", "--data", str(train), "--out", str(folder / "check")],
        "identify": [*cli, "identify", "--data", str(train), *IDENTIFY, "--out", str(folder / "identify")],
        "verify": [*cli, "verify", "--model", str(folder / "identify" / "result.json"), "--data", str(validate),
                   "--run-length", "5", "whole", "--out", str(folder / "verify")],
    }
    row = {"minutes": minutes, "rate_hz": rate, "samples": int(round(60.0 * minutes * rate)) + 1, "steps": {}}
    for name, command in steps.items():
        print(f"[{time.strftime('%H:%M:%S')}] {minutes:g} min: {name} ...", file=sys.stderr, flush=True)
        row["steps"][name] = measured(command)
        print(f"    {row['steps'][name]}", file=sys.stderr, flush=True)
        if row["steps"][name]["returncode"]:
            raise SystemExit(f"long_log: {name} failed on the {minutes:g}-minute flight: {' '.join(command)}")
    verification = json.loads((folder / "verify" / "verification.json").read_text())
    row["verify_pooled"] = {str(v["run_length_s"]): v["pooled"] for v in verification["verifications"]}
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, nargs="+", default=list(MINUTES), help="flight lengths, min")
    parser.add_argument("--rate", type=float, default=RATE_HZ, help="sample rate, Hz (default 250)")
    parser.add_argument("--out", type=Path, required=True, help="folder for the flights, results and long_log.json")
    args = parser.parse_args(argv)
    rows = [one_length(m, args.rate, args.out / f"{m:g}min") for m in args.minutes]
    short, long = rows[0], rows[-1]
    result = {
        "settings": {"rate_hz": args.rate, "minutes": args.minutes, "identify": list(IDENTIFY)},
        "rows": rows,
        "length_ratio": long["samples"] / short["samples"],
        "time_ratio": {k: long["steps"][k]["seconds"] / short["steps"][k]["seconds"] for k in long["steps"]},
        "total_time_ratio": (sum(s["seconds"] for s in long["steps"].values())
                             / sum(s["seconds"] for s in short["steps"].values())),
        "peak_mb": max(s["peak_mb"] for r in rows for s in r["steps"].values()),
    }
    (args.out / "long_log.json").write_text(json.dumps(result, indent=1))
    print(json.dumps({k: result[k] for k in ("length_ratio", "time_ratio", "total_time_ratio", "peak_mb")}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
