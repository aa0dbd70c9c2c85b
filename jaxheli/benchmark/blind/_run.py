"""A blind benchmark run: the protocol's seeds of a split for every kind, then the trials, with ``blind.json`` and
``blind.md`` rewritten after each."""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ...gap.thresholds import THRESHOLDS
from ._flights import TRUTHS_SIM
from ._markdown import markdown
from ._pool import run_blind
from ._summary import summarise_bases
from ._trial import Trial


def run_benchmark(kinds: Sequence[str], seeds: int, out: str | Path, workers: int = 1, iwo_seeds: int = 0,
                  truth: str = "library", split: str = "design", control_seeds: int | None = None,
                  skip_seeds: int = 0, **options: Any) -> dict[str, Any]:
    """Run ``seeds`` blind trials per effect kind and ``control_seeds`` (default ``2 seeds``) of the control
    ``none``, on the first seeds of ``split`` after ``skip_seeds`` (the protocol of :mod:`jaxheli.gap.thresholds`:
    every kind meets the same scenarios), with a PEM base model, and the first ``iwo_seeds`` of them again with an
    IWO + polish base
    (:func:`base_model`), in ``workers`` processes; write ``OUT/blind.json`` (records, :func:`summarise_bases`, the
    settings with the thresholds in force) and ``OUT/blind.md`` after every trial. ``truth`` picks the truth
    simulator (:data:`TRUTHS_SIM`), whose kinds ``kinds`` are."""
    if truth not in TRUTHS_SIM:
        raise ValueError(f"blind benchmark: unknown truth simulator {truth!r}; simulators are {tuple(TRUTHS_SIM)}")
    bad = [k for k in kinds if k not in TRUTHS_SIM[truth]]
    if bad:
        raise ValueError(f"blind benchmark: unknown kinds {bad} for the {truth} truth; kinds are {TRUTHS_SIM[truth]}")
    t0 = time.perf_counter()
    control_seeds = 2 * seeds if control_seeds is None else control_seeds
    drawn = {k: THRESHOLDS.protocol.seeds(split, control_seeds if k == "none" else seeds, skip_seeds) for k in kinds}
    settings = {"kinds": list(kinds), "split": split, "seeds": seeds, "control_seeds": control_seeds,
                "skip_seeds": skip_seeds,
                "seed_range": [min(min(s) for s in drawn.values() if s), max(max(s) for s in drawn.values() if s)],
                "iwo_seeds": iwo_seeds, "workers": workers, "truth": truth, **options,
                "thresholds": {**{f.name: getattr(THRESHOLDS, f.name) for f in dataclasses.fields(THRESHOLDS)
                                  if f.name not in ("protocol", "source")}, "file": THRESHOLDS.source},
                "base_model": "PEM (every trial) or IWO + polish (the first iwo_seeds) on the contaminated "
                              "training flight in the box blind.BOXES[box], never the truth",
                "diagnosis": "joint re-identification (default of jaxheli diagnose)"}
    order = sorted({s for ss in drawn.values() for s in ss})
    trials = ([Trial(k, s) for s in order for k in kinds if s in drawn[k]]
              + [Trial(k, s, "iwo+polish") for k in kinds for s in drawn[k][:iwo_seeds]])
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    def save(records: list[dict[str, Any]]) -> dict[str, Any]:
        summary = summarise_bases(records)
        summary["runtime_s"] = time.perf_counter() - t0
        summary["settings"] = settings
        summary["complete"] = len(records) == len(trials)
        (out / "blind.json").write_text(json.dumps({"summary": summary, "records": records}, indent=2))
        (out / "blind.md").write_text(markdown(summary) + f"\n\nRuntime {summary['runtime_s']:.0f} s.\n")
        return summary

    return save(run_blind(trials, on_trial=save, workers=workers, truth=truth, **options))
