"""The gap diagnosis on the real TREX 550 flights: data consistency of every shared file, then where the
identified model misses, which effect explains it and how far the gap shrinks on data not used for fitting.

Steps (the paper's flights, read from ``$JAXHELI_DATA``):

1. ``jaxheli check`` on every shared flight file (``OUT/consistency/<file>.json``);
2. flight A (``Data_graphready.mat``) trimmed by 50 samples, corrected by its significant findings (time
   base 1.26x slow, v sign-flipped, roll trim), low-passed at ``--lowpass`` Hz and resampled to ``--dt``;
   flight C (``ppr_data.mat``, the paper's validation flight) corrected and resampled the same way;
3. **A -> C**: PEM identifies the model on A; the effects are fitted on A and scored on C;
4. **time split of A** (a longer held-out record): PEM on the first ``--split`` of A, effects fitted on
   the same part, scored on the rest, which neither fit saw.

Writes ``OUT/<pair>/pem/result.json`` (the model), ``OUT/<pair>/diagnosis/`` (``diagnosis.json``, PNGs),
the prepared flights as NPZ (so ``jaxheli diagnose`` can rerun each pair) and ``OUT/summary.md``. Usage::

    python benchmarks/real_diagnosis.py [--lowpass 3.0] [--dt 0.05] [--split 0.6] [--out results/real_diagnosis]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax

import jaxheli
from jaxheli.io.paths import data_dir, data_file
from jaxheli.gap.consistency import check
from jaxheli.cli.diagnosis_text import ranking_table
from jaxheli.gap.diagnose import diagnose, write_diagnosis
from jaxheli.gap.prepare import prepare
from jaxheli.data.preprocess import split
from jaxheli.results import save_result


def check_all(out: Path) -> list[str]:
    """``check`` every file under the data folder that loads as a flight (a log without stick messages with
    zero sticks: the kinematic checks need none); one line per file."""
    lines = []
    for path in sorted(p for p in data_dir().rglob("*") if p.suffix in (".mat", ".px4log", ".bin", ".ulg")):
        name = str(path.relative_to(data_dir()))
        options = {"missing_inputs": "zero"} if path.suffix != ".mat" else {}
        try:
            findings = check(jaxheli.load(path, **options))
        except (ValueError, KeyError) as err:
            lines.append(f"- `{name}`: not checked: {err}")
            continue
        target = out / "consistency" / (name.replace("/", "__") + ".json")
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps([f.to_json() for f in findings], indent=1))
        flagged = [f"{f.kind} ({f.message})" for f in findings if f.significant]
        lines.append(f"- `{name}`: " + ("; ".join(flagged) if flagged else "no significant finding"))
    return lines


def run_pair(name: str, train: jaxheli.FlightData, validate: jaxheli.FlightData, out: Path) -> list[str]:
    """PEM on ``train``, then the diagnosis (effects fitted on ``train``, scored on ``validate``)."""
    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    jaxheli.save_npz(train, folder / "train.npz")
    jaxheli.save_npz(validate, folder / "validate.npz")
    result = jaxheli.identify(train, method="pem", validate=validate)
    save_result(result, folder / "pem", train, validate)
    diagnosis = diagnose(result.params, train, validate)
    write_diagnosis(diagnosis, result.params, validate, folder / "diagnosis")
    pearson = ", ".join(f"{c} {v:.3f}" for c, v in result.validate["pearson"].items())
    return [f"### {name}: train {train.source} ({train.duration:.1f} s), validate {validate.source} "
            f"({validate.duration:.1f} s)", "", f"PEM validation Pearson: {pearson}", "",
            f"Largest gap: `{json.dumps(diagnosis.localisation.summary.to_json())}`", "", "```",
            *ranking_table(diagnosis), "```", "", f"Verdict: {diagnosis.attribution.verdict}", ""]


def main(argv: list[str] | None = None) -> int:
    jaxheli.configure_xla()
    jax.config.update("jax_enable_x64", True)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lowpass", type=float, default=3.0, help="low-pass cutoff of flight A, Hz")
    parser.add_argument("--dt", type=float, default=0.05, help="resampling step of both flights, s")
    parser.add_argument("--split", type=float, default=0.6, help="fitted fraction of A in the time split")
    parser.add_argument("--out", default="results/real_diagnosis")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# Gap diagnosis on the real TREX 550 flights", "", "## Consistency of every shared file", "",
             *check_all(out), ""]
    flight_a = prepare(jaxheli.load(data_file("trex550/Data_graphready.mat")), correct_data=True, trim_samples=50,
                       lowpass_hz=args.lowpass, dt=args.dt)
    flight_c = prepare(jaxheli.load(data_file("trex550/ppr_data.mat")), correct_data=True, dt=args.dt)
    lines += ["## Diagnoses", "", *run_pair("A_to_C", flight_a, flight_c, out)]
    lines += run_pair("A_split", *split(flight_a, args.split), out)
    (out / "summary.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
