"""The Benchmarks page, generated from the measurement records in ``docs/benchmarks/*.json``.

A record is one command's JSON output with what it takes to read it: the command, the commit it ran on, the
machine, the date and a label (measured or estimated; in-sample or held-out; design or test seeds). No figure on
the page is typed by hand: every number comes from a record.

Write a record by running the command through this script (it times the run and reads back the JSON file the
command wrote)::

    python docs/gen_benchmarks.py record main-job --kind identify --json /tmp/rd/result.json \\
        --title "..." --measure measured --sample in-sample \\
        "jaxheli identify --data default --iterations 100 --out /tmp/rd"

``python docs/gen_benchmarks.py render`` prints the page; ``mkdocs build`` renders it through ``docs/hooks.py``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

DOCS = Path(__file__).resolve().parent
RECORDS = DOCS / "benchmarks"
ROOT = DOCS.parent

MEASURES = ("measured", "estimated")
SAMPLES = ("in-sample", "held-out", "unknown", "not applicable")
SEEDS = ("design", "calibration", "test", "not applicable")


# --- writing a record ------------------------------------------------------------------------------------------


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()


def machine() -> dict:
    """The machine a record was measured on: OS, architecture, CPU model and count, load, Python and JAX."""
    processor = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                processor = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    info = {
        "system": f"{platform.system()} {platform.release()}",
        "arch": platform.machine(),
        "processor": processor,
        "cpus": os.cpu_count(),
        "load_1min": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None,
        "python": platform.python_version(),
    }
    try:
        import jax

        info["jax"] = jax.__version__
        info["device"] = str(jax.devices()[0].device_kind)
    except Exception:  # noqa: BLE001 - a record without JAX still says the rest
        pass
    return info


def record(name: str, kind: str, command: str, json_path: Path, *, title: str, measure: str, sample: str,
           seeds: str, note: str = "", ran_s: float | None = None, keep: str | None = None) -> dict:
    """Run ``command`` (a shell command line, from the repository root), read the JSON it writes at ``json_path``
    and store it with its metadata as ``docs/benchmarks/NAME.json``; the record keeps the command as written
    (``$JAXHELI_DATA`` unexpanded). ``ran_s``: the command already ran, taking that long by the caller's clock; its
    output is stored without running it again (the record says so, and ``note`` says with which code where that is
    not this commit's). ``keep``: store only that top-level entry of the JSON (e.g. ``summary`` of a blind check's
    ``blind.json``, whose per-trial records run to megabytes)."""
    load_before = machine()["load_1min"]
    if ran_s is None:
        start = time.perf_counter()
        subprocess.run(["bash", "-c", command], cwd=ROOT, check=True)
        wall = time.perf_counter() - start
    else:
        wall, load_before = ran_s, None
        note = (note + " " if note else "") + "Run before the record was written; its output stored."
    status = _git("status", "--porcelain", "--untracked-files=no", "--", "jaxheli", "pyproject.toml")
    rec = {
        "title": title,
        "kind": kind,
        "command": command,
        "commit": _git("rev-parse", "HEAD"),
        "code_dirty": bool(status),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": {**machine(), "load_1min_before": load_before},
        "label": {"measure": measure, "sample": sample, "seeds": seeds, "note": note},
        "wall_s": round(wall, 1),
        "output": _kept(json.loads(Path(json_path).read_text()), keep),
    }
    RECORDS.mkdir(exist_ok=True)
    (RECORDS / f"{name}.json").write_text(json.dumps(_finite(rec), indent=1) + "\n")
    return rec


def _kept(output: dict, keep: str | None) -> dict:
    """``output``, or only its entry ``keep`` (an error naming the entries there are when it has none)."""
    if keep is None:
        return output
    if keep not in output:
        raise ValueError(f"record: the JSON has no entry {keep!r}; it has {sorted(output)}")
    return output[keep]


def _finite(value):
    """``value`` with non-finite floats as strings (strict JSON)."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


# --- rendering -------------------------------------------------------------------------------------------------


def load_records(folder: Path = RECORDS) -> list[tuple[str, dict]]:
    """``(name, record)`` for every ``*.json`` in ``folder``, by name."""
    return [(path.stem, json.loads(path.read_text())) for path in sorted(folder.glob("*.json"))]


def _num(value, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return f"{value:,}"
    if not math.isfinite(value):
        return str(value)
    if float(value).is_integer() and abs(value) < 1e6:
        return f"{int(value):,}"
    if abs(value) >= 1000:
        return f"{value:,.0f}"
    return f"{value:.{digits}g}" if abs(value) < 1 else f"{value:.{max(digits - len(str(int(abs(value)))), 1)}f}"


def _table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_num(c) if not isinstance(c, str) else c for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _metadata(rec: dict) -> str:
    m = rec["machine"]
    label = rec["label"]
    device = f", {m['device']}" if m.get("device") else ""
    jax = f", JAX {m['jax']}" if m.get("jax") else ""
    dirty = " (with uncommitted changes to the code)" if rec.get("code_dirty") else ""
    rows = [
        ("command", f"`{rec['command']}`"),
        ("commit", f"`{rec['commit']}`{dirty}"),
        ("machine", f"{m['processor']}, {m['cpus']} CPUs{device}, {m['system']}, Python {m['python']}{jax}; load "
                    + (f"average {m['load_1min_before']} before the run, " if m.get("load_1min_before") is not None
                       else "average ")
                    + f"{m.get('load_1min', '-')} when recorded"),
        ("date", rec["date"]),
        ("label", f"**{label['measure']}**; sample: {label['sample']}; seeds: {label['seeds']}"),
        ("wall time of the command", f"{_num(rec['wall_s'])} s (measured)"),
    ]
    if label.get("note"):
        rows.append(("note", label["note"]))
    return "\n".join(["| | |", "|---|---|"] + [f"| {k} | {v} |" for k, v in rows])


def _metric_rows(block: dict, metrics: tuple[str, ...]) -> list[list]:
    channels = block["channels"] if "channels" in block else list(block[metrics[0]])
    return [[f"`{ch}`"] + [block[m][ch] if isinstance(block[m], dict) else block[m][i] for m in metrics]
            for i, ch in enumerate(channels)]


def render_identify(rec: dict) -> str:
    out = rec["output"]
    parts = []
    for split in ("train", "validate"):
        block = out.get(split)
        if not block:
            continue
        truth = (out.get("truth") or {}).get(split) or {}
        names = {"pearson": "Pearson", "tic": "TIC", "fit_percent": "fit %"}
        header = ["channel"] + [f"model {names[m]}" for m in names]
        if truth:
            header += [f"truth {names[m]}" for m in names] + ["model - truth fit %"]
        rows = []
        for ch in block["pearson"]:
            row = [f"`{ch}`"] + [block[m][ch] for m in names]
            if truth:
                row += [truth[m][ch] for m in names] + [round(block["fit_percent"][ch] - truth["fit_percent"][ch], 2)]
            rows.append(row)
        sample = "in-sample: the flight the model was fitted to" if split == "train" else "held out"
        parts.append(f"**{split}** ({sample}; fit % in percent, TIC 0 is a perfect match):\n\n" + _table(header, rows))
    extra = []
    cr = (out.get("truth") or {}).get("cramer_rao")
    if cr:
        within, identifiable = (len(v) if isinstance(v, list) else v for v in (cr["within"], cr["identifiable"]))
        extra.append([f"identifiable parameters within {_num(cr.get('k', 3))} Cramer-Rao standard errors of the truth",
                      f"{within} of {identifiable}"])
    freq = out.get("frequency") or {}
    if "j_average" in freq:
        extra.append(["Tischler's J, average over the input-output pairs (<= 100 acceptable)", freq["j_average"]])
    if out.get("seconds") is not None:
        extra.append(["seconds to fit (the result's own clock)", out["seconds"]])
    if extra:
        parts.append(_table(["", "value"], extra))
    return "\n\n".join(parts)


def render_verify(rec: dict) -> str:
    """One table per verified flight: the scores pooled over its runs, per channel and overall."""
    parts = []
    metrics = ("tic", "pearson", "fit_percent", "j_rms")
    for v in rec["output"]["verifications"]:
        pooled = v["pooled"]
        rows = [[f"`{ch}`"] + [pooled[m].get(ch) for m in metrics] for ch in v["channels"]]
        rows.append(["**overall**"] + [pooled[m].get("overall") for m in metrics])
        n = len(v["runs"])
        length = "the whole window" if v["run_length_s"] is None else f"{_num(v['run_length_s'])} s"
        parts.append(f"`{Path(v['source']).name}`: {n} run{'s' if n != 1 else ''} of {length}, scores pooled over them:\n\n"
                     + _table(["channel", "TIC", "Pearson", "fit %", "J_rms"], rows))
    return "\n\n".join(parts)


def render_truth_forms(rec: dict) -> str:
    """One row per kind and truth: the effect's size and the residual its nearest candidate leaves, in sensor-noise
    std, per seed."""
    rows = [[r["truth"], f"`{r['kind']}`", r["row"], r["seed"], r["size"], r["residual"], f"`{r['nearest']}`",
             "yes" if r["residual"] <= 1.0 else "no"] for r in rec["output"]["rows"]]
    return ("Noise-free flights; the nearest candidate fitted alone with the truth's own hover model under the "
            "diagnosis's predictor. A residual above 1 (sensor-noise std) puts the kind outside the candidate's "
            "family.\n\n" + _table(["truth", "kind", "row", "seed", "size", "residual", "nearest candidate",
                                    "within the noise"], rows))


def render_suite_time(rec: dict) -> str:
    """The suite of the tested commit against the reference's, run one after the other in clean clones on one
    machine, and the tested commit's CI time estimated from the reference's."""
    out = rec["output"]
    rows = [[role, f"`{run['commit'][:10]}`", ", ".join(f"{n} {k}" for k, n in run["counts"].items()),
             _num(run["pytest_s"], 4)] for role, run in (("reference", out["reference"]), ("tested", out["tested"]))]
    text = (f"README's test command in clean clones, the reference first. Ratio tested / reference: "
            f"**{_num(out['ratio'])}** (measured).")
    if out.get("estimated_ci_s") is not None:
        text += (f" The reference took {_num(out['reference_ci_s'], 4)} s in CI when the suite's limit was set; at "
                 f"that machine's speed the tested suite would take **{_num(out['estimated_ci_s'], 4)} s** "
                 "(estimated: the ratio times it).")
    return text + "\n\n" + _table(["suite", "commit", "tests", "pytest (s)"], rows)


def _modes_cell(found: list[dict]) -> str:
    """Unstable modes (eigenvalues with positive real part, 1/s) in one cell: ``+0.05``, ``+0.3 +- 0.1j``."""
    return ", ".join(f"{m['eigenvalue'][0]:+.3g}" + (f" +- {m['eigenvalue'][1]:.3g}j" if m["eigenvalue"][1] else "")
                     for m in found) or "none"


RECIPE_CHANNELS = ("p", "q", "phi", "theta")
"""The channels the recipes are compared on (``benchmarks/identification.py real``)."""


def render_recipes(rec: dict) -> str:
    """``benchmarks/identification.py real --recipes ...``: one row per training record, recipe and validation
    record, labelled held out or in-sample: Pearson, fit % and TIC per channel over 5-s runs (``jaxheli verify``),
    the model's unstable modes, the parameters the structure determination fixed and the fit's seconds."""
    rows = rec["output"]["rows"]
    channels = [c for c in RECIPE_CHANNELS if rows and c in rows[0]["runs"]["pearson"]]
    metrics = (("pearson", "r", ".3f"), ("fit_percent", "fit %", ".1f"), ("tic", "TIC", ".3f"))
    seeds = len(rec["output"].get("settings", {}).get("seeds", [])) > 1
    header = (["train", "recipe", "validate", "sample"] + (["seed"] if seeds else [])
              + [f"{short} {c}" for _, short, _ in metrics for c in channels]
              + ["unstable modes (1/s)", "fixed", "fit s"])
    body = [[r["train"], r["method"] if r["recipe"] == "-" else r["recipe"], r["validate"], f"**{r['sample']}**"]
            + ([str(r.get("seed", "-"))] if seeds else [])
            + [f"{r['runs'][m][c]:{fmt}}" for m, _, fmt in metrics for c in channels]
            + [_modes_cell(r["unstable_modes"])]
            + (["-", "-"] if r["recipe"] == "-" else [str(len(r.get("fixed") or [])), f"{r['seconds']:.0f}"])
            for r in rows]
    settings = rec["output"].get("settings", {})
    methods = ", ".join(f"`{m}`" for m in settings.get("methods", []))
    return (f"Recipes of {methods} (issue 66): `default` is the authors' box (`jaxheli identify`'s default); "
            "`physical` the physical box (`--box wide`, `jaxheli.model.WIDE_LOWER`/`WIDE_UPPER`); `structure` the "
            "model-structure determination after the fit (`--structure`; *fixed*: how many parameters it fixed); "
            "`prior` a Gaussian prior toward the paper's Table 2 in the local fits (`--prior table2`). "
            f"{settings.get('iterations')} IWO generations. Scores over 5-s runs, each from its least-squares start with a "
            "per-channel bias (`jaxheli verify`); sample: **held out** (the validation record is not part of the "
            "training record), **in-sample** (it is), **unknown** (Table 2: its training flight is not recorded). "
            "*fit s*: wall seconds of the fit on this machine.\n\n" + _table(header, body))


def render_long_log(rec: dict) -> str:
    """``benchmarks/long_log.py``: each step's wall seconds and peak memory per flight length, and the longest
    flight's time over the shortest's."""
    out = rec["output"]
    steps = list(out["rows"][0]["steps"])
    header = ["flight", "samples"] + [f"{s} s" for s in steps] + ["total s"] + [f"{s} peak MB" for s in steps]
    rows = [[f"{r['minutes']:g} min at {r['rate_hz']:g} Hz", r["samples"]]
            + [_num(r["steps"][s]["seconds"], 4) for s in steps]
            + [_num(sum(r["steps"][s]["seconds"] for s in steps), 4)]
            + [_num(r["steps"][s]["peak_mb"], 4) for s in steps] for r in out["rows"]]
    ratios = ", ".join(f"{s} {_num(out['time_ratio'][s])}x" for s in steps)
    settings = " ".join(out["settings"]["identify"])
    return (f"Each step a fresh process, as the command line runs it (`jaxheli identify {settings}`, the default method; `jaxheli verify` over 5-s runs and one whole run on a second flight). A "
            f"{_num(out['length_ratio'])}x longer record takes **{_num(out['total_time_ratio'])}x** the time "
            f"({ratios}); peak resident memory of any step **{_num(out['peak_mb'], 4)} MB**.\n\n"
            + _table(header, rows))


def render_time_forms(rec: dict) -> str:
    """``jaxheli bench`` (its ``bench.json``'s ``time_forms``, stored with ``--keep time_forms``): the plain scan
    against the parallel form of each recursion in time, per flight length and population, and the table chosen."""
    out = rec["output"]
    header = ["path", "dtype", "N", "P / tangents", "steps", "scan s", "parallel s", "parallel / scan",
              "largest relative difference"]
    rows = [[r["path"], r["dtype"], r["N"], r.get("P", r.get("tangents")), r["steps"], _num(r["scan_s"], 3),
             _num(r.get("parallel_s"), 3) if "parallel_s" in r else r.get("skipped", "-"),
             _num(r.get("parallel_over_scan"), 3) if "parallel_s" in r else "-",
             f"{r['difference']:.1e}" if "difference" in r else "-"] for r in out["rows"]]
    chosen = ", ".join(f"{path} {'never' if steps is None else f'from {steps} steps'}"
                       for table in out["selection"].values() for path, steps in table.items())
    return (f"Backend `{out['backend']}` ({out['device']}). Each row times one call of each form alternately, best "
            "of the repeats after a compiling call; the difference is the largest between the forms' results "
            "relative to the largest value (`jaxheli/benchmark/time_forms.py`). The table the simulator reads on "
            f"this backend (`jaxheli/sim/forms.py`), where the parallel form takes over: {chosen}.\n\n"
            + _table(header, rows))


def _beyond(row: dict, subset: str) -> str:
    """A kind's (or pool's) trials in ``subset`` (``explainable_beyond_structure``: the oracle shrinks the gap beyond
    the structure too; ``beyond_structure``: a hover model alone cannot take the effect up) and its top-1 % there
    ("-" in records from before that measure, or for the controls)."""
    if f"{subset}_trials" not in row:
        return "-"
    top = row.get(f"top1_{subset}_pct")
    return f"{row[f'{subset}_trials']}, {'-' if top is None else f'{top:.0f}'}"


def render_blind(rec: dict) -> str:
    """``jaxheli blind`` (its ``blind.json``'s ``summary``, stored with ``--keep summary``): per kind, top-1 over all
    trials, over the resolvable ones and over those beyond the structure's reach (a hover model fitted alone leaves
    more than the noise), the median magnitude error there, how often the base model's structure was named and the
    trials explainable beyond it (a diagnostic: the oracle shrinks the gap there too); top-1
    pooled by form (in family: the nearest candidate comes within the noise; other forms); the
    controls that named an effect."""
    from jaxheli.benchmark.truth import IN_FAMILY

    out = rec["output"]
    set_ = out["settings"]
    pct = lambda v: "-" if v is None else f"{v:.0f}"
    err = lambda v: "-" if v is None or isinstance(v, str) else f"{100 * v:.0f} %"
    rows = [[f"`{kind}`", "control" if kind == "none" else ("in family" if kind in IN_FAMILY else "other forms"),
             k["trials"], pct(k.get("top1_pct")), k.get("resolvable_trials", "-"), pct(k.get("top1_resolvable_pct")),
             err(k.get("magnitude_error_median_resolvable")), _beyond(k, "beyond_structure"),
             pct(k.get("structure_pct")), _beyond(k, "explainable_beyond_structure")]
            for kind, k in out["kinds"].items()]
    pooled = [[label, f["trials"], pct(f["top1_pct"]), f["resolvable_trials"], pct(f.get("top1_resolvable_pct")),
               err(f.get("magnitude_error_median_resolvable")), _beyond(f, "beyond_structure")]
              for label, f in out.get("forms", {}).items()]
    low, high = out["false_positive_ci95_pct"]
    return (f"The `{set_['truth']}` simulator, `{set_['truths']}` truths, `{set_['split']}` seeds "
            f"{set_['seed_range'][0]}-{set_['seed_range'][1]} a kind; base models identified by `{set_['base']}` "
            f"in the `{set_['box']}` box, {set_['duration']:g}-s flights at {1 / set_['dt']:g} Hz. Top-1: the "
            "verdict names a right candidate first; resolvable: the effect shows on the training flight as on the "
            "validation flight, decided by the simulator before any fit; beyond the structure's reach: resolvable, and "
            "a hover model fitted alone to the noise-free training flight leaves more than the sensor noise of the "
            "effect on the validation flight (`docs/guide/blind.md`).\n\n"
            + _table(["kind", "form", "trials", "top-1 %", "resolvable", "top-1 % resolvable",
                      "median magnitude error (resolvable)", "beyond the structure's reach: trials, top-1 %",
                      "structure named %", "explainable beyond the structure: trials, top-1 %"], rows)
            + "\n\n" + _table(["pooled", "trials", "top-1 %", "resolvable", "top-1 % resolvable",
                                 "median magnitude error (resolvable)",
                                 "beyond the structure's reach: trials, top-1 %"], pooled)
            + f"\n\nControls that named an effect: **{out['false_positives']} of {out['controls']}** (95 % Wilson "
              f"interval {low:.0f}-{high:.0f} %).")


RENDERERS = {"identify": render_identify, "verify": render_verify, "truth_forms": render_truth_forms,
             "suite_time": render_suite_time, "recipes": render_recipes, "long_log": render_long_log,
             "blind": render_blind, "time_forms": render_time_forms}
"""How each kind of record is drawn; a new kind (e.g. ``bench.json``) needs its renderer here."""

INTRO = """# Benchmarks

Every figure on this page is read from a record in `docs/benchmarks/*.json` (this page is generated by
`docs/gen_benchmarks.py` when the site is built; no number here is typed by hand). Each record keeps the command
that produced it, the commit it ran on, the machine, and its label: **measured** or **estimated**, **in-sample**
(scored on the flight the model was fitted to) or **held-out**, and which seeds (design, calibration or test seeds of
the blind check's protocol, `jaxheli/gap/thresholds.json`). A record is re-measured by running its command again:

```bash
python docs/gen_benchmarks.py record NAME --kind KIND --json OUTPUT.json --title TITLE \\
    --measure measured --sample in-sample --seeds "not applicable" "COMMAND"
```

The earlier figures, with their commits, commands and conditions, are the lab notebook:
[performance history](performance_history.md) (timings of the main job, `jaxheli bench`, the diagnosis, the test
suite) and [blind-check history](blind_history.md) (every held-out test of the gap diagnosis and the design-seed
studies behind its rules).
"""


def render(records: list[tuple[str, dict]]) -> str:
    parts = [INTRO]
    for name, rec in records:
        renderer = RENDERERS.get(rec.get("kind"))
        body = renderer(rec) if renderer else "(no renderer for this kind of record)"
        parts.append(f"## {rec['title']}\n\nRecord `docs/benchmarks/{name}.json`.\n\n{_metadata(rec)}\n\n{body}\n")
    if not records:
        parts.append("No records yet.\n")
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="action", required=True)
    rec = sub.add_parser("record", help="run a command and store its JSON output with the metadata")
    rec.add_argument("name", help="the record's file name in docs/benchmarks/ (without .json)")
    rec.add_argument("--kind", required=True, choices=sorted(RENDERERS))
    rec.add_argument("--json", required=True, type=Path, help="the JSON file the command writes")
    rec.add_argument("--title", required=True)
    rec.add_argument("--measure", choices=MEASURES, default="measured")
    rec.add_argument("--sample", choices=SAMPLES, required=True)
    rec.add_argument("--seeds", choices=SEEDS, default="not applicable")
    rec.add_argument("--note", default="")
    rec.add_argument("--ran", type=float, default=None, metavar="SECONDS",
                     help="the command already ran (taking SECONDS): store its JSON without running it again")
    rec.add_argument("--keep", default=None, metavar="KEY",
                     help="store only this top-level entry of the JSON (a blind check's: summary)")
    rec.add_argument("command", help="the command line, one argument (run by bash from the repository root)")
    sub.add_parser("render", help="print the page")
    args = parser.parse_args(argv)
    if args.action == "render":
        print(render(load_records()))
        return 0
    record(args.name, args.kind, args.command, args.json, title=args.title, measure=args.measure, sample=args.sample,
           seeds=args.seeds, note=args.note, ran_s=args.ran, keep=args.keep)
    return 0


if __name__ == "__main__":
    sys.exit(main())
