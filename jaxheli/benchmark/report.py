"""The benchmark's markdown tables, its throughput plot and its files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def markdown(result: dict) -> str:
    """Tables of a ``jaxheli bench`` result: throughput over P and N, IWO generations, experiment, devices."""
    lines = [f"# jaxheli bench: {result['machine']}", ""]
    lines += ["## Population cost: candidate evaluations per second", "",
              "| dtype | N | P | scan /s | blocked /s | NumPy loop /s | blocked x NumPy | blocked x scan "
              "| FLOP-limit /s | blocked / limit |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["rates"]:
        scan, blocked, base = r.get("scan", np.nan), r.get("blocked", np.nan), r["numpy"]
        lines.append(f"| {r['dtype']} | {r['N']} | {r['P']} | {scan:.0f} | {blocked:.0f} | {base:.1f} | "
                     f"{blocked / base:.0f} | {blocked / scan:.1f} | {r['flop_limit']:.0f} | "
                     f"{blocked / r['flop_limit']:.2f} |")
    if result.get("mealpy"):
        lines += ["", "mealpy OriginalIWO on the NumPy cost, N = {N}: {rate:.1f} evaluations/s".format(**result["mealpy"])]
    if result.get("iwo_generation"):
        lines += ["", "## Seconds per IWO generation (the real seeds of a 280-slot buffer)", "", "| dtype | N | method | s/generation |",
                  "|---|---|---|---|"]
        lines += [f"| {g['dtype']} | {g['N']} | {g['method']} | {g['seconds']:.4f} |" for g in result["iwo_generation"]]
    if result.get("time_forms"):
        tf = result["time_forms"]
        lines += ["", f"## Recursions in time: plain scan against the parallel form ({tf['backend']}, {tf['device']})",
                  "", "Best of the repeats, the two forms timed alternately; the difference is the largest between "
                  "their results, relative to the largest result.", "",
                  "| path | dtype | N | P / tangents | steps | scan s | parallel s | parallel / scan | difference |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in tf["rows"]:
            size = r.get("P", r.get("tangents"))
            par = (f"{r['parallel_s']:.4g} | {r['parallel_over_scan']:.2f} | {r['difference']:.1e}"
                   if "parallel_s" in r else f"skipped ({r.get('skipped')}) | - | -")
            lines.append(f"| {r['path']} | {r['dtype']} | {r['N']} | {size} | {r['steps']} | {r['scan_s']:.4g} | "
                         f"{par} |")
        lines += ["", "Selected table (the fewest steps from which the parallel form is used; none: never): "
                      f"`{json.dumps(tf['selection'])}`"]
    for e in result.get("experiments") or ([result["experiment"]] if result.get("experiment") else []):
        base = e["evaluations"] / e["numpy_rate"]
        form = f", time form {e['time_form']} ({e['resolved_form']})" if "time_form" in e else ""
        lines += ["", "## The paper's whole experiment", "",
                  f"{e['trials']} trials x {e['iterations']} IWO generations on {e['flight']} ({e['samples']} samples, "
                  f"{e['dtype']}, {e['method']} kernel{form}, {e['devices']} device(s)): **{e['seconds']:.1f} s** end "
                  f"to end including compilation, {e['evaluations']:,} candidates scored "
                  f"({e['evaluations_per_s']:.0f}/s). The per-candidate NumPy loop would take {base:.0f} s "
                  f"({base / 3600:.1f} h): {base / e['seconds']:.0f}x longer."]
    if result.get("costs"):
        c = result["costs"]
        lines += ["", f"## Costs the engines minimise (N = {c['N']}, P = {c['P']}, float64, compiled)", "",
                  "| cost | candidates/s | ratio to Pearson |", "|---|---|---|"]
        lines += [f"| {r['cost']} | {r['rate']:.0f} | {r['ratio']:.2f} |" for r in c["rows"]]
    if result.get("time_to_model"):
        lines += ["", "## Time to a model (compilation included)", "",
                  "Each method in a fresh process, as `jaxheli identify` runs: JAX's default devices "
                  f"({', '.join(sorted({str(r.get('devices', '?')) for r in result['time_to_model']}))}), "
                  "nothing compiled before it, no persistent cache.", "",
                  "| method | fit step s | time form | samples | s (measured) | NumPy loop s (estimated) | ratio "
                  "| fit % p / q / phi / theta |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in result["time_to_model"]:
            fit = " / ".join(f"{r['fit_percent'][c]:.1f}" for c in ("p", "q", "phi", "theta")
                             if c in r.get("fit_percent", {})) or f"RSS {r['rss']:.4g} ({r['steps']} steps)"
            numpy = f"{r['numpy_seconds']:.0f} | {r['numpy_ratio']:.0f}x" if "numpy_seconds" in r else "- | -"
            step = "own" if not r.get("fit_dt") else " / ".join(f"{d:.4g}" for d in r["fit_dt"])
            lines.append(f"| {r['method']} | {step} | {r.get('time_form', 'auto')} | {r['samples']} | "
                         f"{r['seconds']:.1f} | {numpy} | {fit} |")
        if any("numpy_seconds" in r and r["method"].startswith("iwo") for r in result["time_to_model"]):
            lines += ["", "IWO's NumPy loop: the candidates IWO scored, at the loop's rate measured in this run (an "
                          "estimate, not a run; the frequency fit and the polish are not counted in it)."]
        if any("numpy_simulations" in r and r["method"] == "pem" for r in result["time_to_model"]):
            lines += ["", "PEM's NumPy loop: a forward-difference Jacobian per step, steps x (free parameters + 1) "
                          "simulations at the loop's measured rate (an estimate, not a run)."]
    if result.get("scaling"):
        lines += ["", "## Sharding over local devices", "", "| dtype | N | P | 1 device /s | "
                  f"{result['devices']} devices /s | speed-up | efficiency |", "|---|---|---|---|---|---|---|"]
        for s in result["scaling"]:
            speedup = s["sharded"] / s["single"]
            lines.append(f"| {s['dtype']} | {s['N']} | {s['P']} | {s['single']:.0f} | {s['sharded']:.0f} | "
                         f"{speedup:.2f} | {speedup / result['devices']:.2f} |")
    return "\n".join(lines) + "\n"


def plot_throughput(result: dict, path: str | Path) -> Path:
    """Evaluations per second against population size, one line per method, dtype and flight length."""
    from ..plots import _subplots

    fig, ax = _subplots(figsize=(7, 4.5))
    rows = result["rates"]
    for dtype in sorted({r["dtype"] for r in rows}):
        for n in sorted({r["N"] for r in rows}):
            sel = sorted((r for r in rows if r["dtype"] == dtype and r["N"] == n), key=lambda r: r["P"])
            P = [r["P"] for r in sel]
            for method, style in (("blocked", "-"), ("scan", "--")):
                if all(method in r for r in sel):
                    ax.loglog(P, [r[method] for r in sel], style, marker="o", label=f"{method} {dtype} N={n}")
            ax.loglog(P, [r["numpy"] for r in sel], ":", color="grey")
    ax.set_xlabel("population size P")
    ax.set_ylabel("candidate evaluations / s")
    ax.set_title("population cost throughput (dotted: per-candidate NumPy loop)")
    ax.grid(True, which="both", alpha=0.3)
    if rows:
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return Path(path)


def write_bench(result: dict, out: str | Path) -> list[Path]:
    """Write ``bench.json`` (``result``), ``bench.md`` (:func:`markdown`) and ``throughput.png``
    (:func:`plot_throughput`) into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench.json").write_text(json.dumps(result, indent=2))
    (out / "bench.md").write_text(markdown(result))
    return [out / "bench.json", out / "bench.md", plot_throughput(result, out / "throughput.png")]
