"""A blind benchmark run: the protocol's seeds of a split for every kind (refused where the ledger holds them
spent), recorded in the ledger before any trial flies, then the trials, with ``blind.json`` and ``blind.md``
rewritten after each."""

from __future__ import annotations

import dataclasses
import json
import os
import shlex
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ...gap.thresholds import THRESHOLDS
from ...gap import ledger
from ._flights import TRUTHS_SIM
from ._markdown import markdown
from ._pool import run_blind
from ._summary import summarise_bases
from ._trial import Trial


def run_benchmark(kinds: Sequence[str], seeds: int, out: str | Path, workers: int = 1, iwo_seeds: int = 0,
                  truth: str = "library", split: str = "design", control_seeds: int | None = None,
                  skip_seeds: int = 0, refly_design: bool = False, base: str = "pem",
                  **options: Any) -> dict[str, Any]:
    """Run ``seeds`` blind trials per effect kind and ``control_seeds`` (default ``2 seeds``) of the control
    ``none``, on the first seeds of ``split`` after ``skip_seeds`` (the protocol of :mod:`jaxheli.gap.thresholds`:
    every kind meets the same scenarios; spent seeds are refused, design ones flown again only with
    ``refly_design``), with a ``base`` model (default PEM), and the first ``iwo_seeds`` of them again with an IWO +
    polish base (:func:`~jaxheli.benchmark.blind.base_model`), in ``workers`` processes. Every seed drawn is appended to the
    seed ledger (:mod:`jaxheli.gap.ledger`) before the first trial; on the test split a second look under the
    same rules and simulator is refused first (:func:`~jaxheli.gap.ledger.refuse_second_look`). Writes
    ``OUT/blind.json`` (records, :func:`~jaxheli.benchmark.blind.summarise_bases`, the settings with the thresholds
    in force and the ledger entry) and ``OUT/blind.md`` after every trial. ``truth`` picks the truth simulator
    (:data:`~jaxheli.benchmark.blind.TRUTHS_SIM`), whose kinds ``kinds`` are."""
    if truth not in TRUTHS_SIM:
        raise ValueError(f"blind benchmark: unknown truth simulator {truth!r}; simulators are {tuple(TRUTHS_SIM)}")
    bad = [k for k in kinds if k not in TRUTHS_SIM[truth]]
    if bad:
        raise ValueError(f"blind benchmark: unknown kinds {bad} for the {truth} truth; kinds are {TRUTHS_SIM[truth]}")
    control_seeds = 2 * seeds if control_seeds is None else control_seeds
    drawn = {k: THRESHOLDS.protocol.seeds(split, control_seeds if k == "none" else seeds, skip_seeds,
                                          refly=refly_design) for k in kinds}
    thresholds = thresholds_in_force()
    rules = ledger.rule_id(thresholds)
    if split == "test":
        ledger.refuse_second_look(truth, rules)
    entry = ledger.Entry({k: ledger.spans(s) for k, s in drawn.items() if s}, split, truth, ledger.now(),
                         _command(kinds, seeds, truth=truth, split=split, control_seeds=control_seeds,
                                  skip_seeds=skip_seeds, iwo_seeds=iwo_seeds, workers=workers,
                                  refly_design=refly_design, base=base, **options),
                         look=split == "test", rules=rules, commit=ledger.head_commit())
    settings = {"kinds": list(kinds), "split": split, "seeds": seeds, "control_seeds": control_seeds,
                "skip_seeds": skip_seeds,
                "seed_range": [min(min(s) for s in drawn.values() if s), max(max(s) for s in drawn.values() if s)],
                "iwo_seeds": iwo_seeds, "workers": workers, "truth": truth, "base": base, **options,
                "thresholds": {**thresholds, "file": THRESHOLDS.source},
                "base_model": f"{base} (every trial) or IWO + polish (the first iwo_seeds) on the contaminated "
                              "training flight in the box blind.BOXES[box], never the truth",
                "diagnosis": "joint re-identification (default of jaxheli diagnose)",
                "ledger": {"file": str(ledger.path()), "entry": entry.to_json()}}
    trials = trial_list(kinds, drawn, base, iwo_seeds)
    Path(out).mkdir(parents=True, exist_ok=True)
    ledger.append(entry)
    return fly(trials, out, settings, [], workers=workers, truth=truth, **options)


def thresholds_in_force() -> dict[str, Any]:
    """The threshold values in force (:data:`~jaxheli.gap.thresholds.THRESHOLDS`), name to value, without the
    protocol and the file's name: what :func:`~jaxheli.gap.ledger.rule_id` hashes with the rule code."""
    return {f.name: getattr(THRESHOLDS, f.name) for f in dataclasses.fields(THRESHOLDS)
            if f.name not in ("protocol", "source")}


def trial_list(kinds: Sequence[str], drawn: Mapping[str, Sequence[int]], base: str, iwo_seeds: int) -> list[Trial]:
    """A run's trials, in the order they fly: every kind's trial on each seed in turn (``drawn`` maps a kind to its
    seeds), then the first ``iwo_seeds`` of each kind again with an IWO + polish base."""
    order = sorted({s for ss in drawn.values() for s in ss})
    return ([Trial(k, s, base) for s in order for k in kinds if s in drawn[k]]
            + [Trial(k, s, "iwo+polish") for k in kinds for s in list(drawn[k])[:iwo_seeds]])


def fly(trials: Sequence[Trial], out: str | Path, settings: dict[str, Any], done: Sequence[dict[str, Any]],
        *, workers: int = 1, prior_s: float = 0.0, **options: Any) -> dict[str, Any]:
    """Fly the ``trials`` that the records ``done`` (an earlier part of the run, matched by :func:`trial_key`) do
    not hold, in ``workers`` processes with the trial ``options``; after every trial write ``OUT/blind.json``
    (every record in the order of ``trials``, their :func:`summarise_bases`, ``settings``, whether the run is
    ``complete`` and its ``runtime_s``, ``prior_s`` of earlier parts included) and ``OUT/blind.md``. The summary."""
    t0 = time.perf_counter()
    held = {trial_key(r): r for r in done}
    todo = [t for t in trials if trial_key(t) not in held]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    def save(records: list[dict[str, Any]]) -> dict[str, Any]:
        found = {**held, **{trial_key(r): r for r in records}}
        ordered = [found[trial_key(t)] for t in trials if trial_key(t) in found]
        summary = summarise_bases(ordered)
        summary["runtime_s"] = prior_s + time.perf_counter() - t0
        summary["settings"] = settings
        summary["complete"] = len(ordered) == len(trials)
        partial = out / "blind.json.tmp"  # moved into place whole: a run killed while writing keeps its last record
        partial.write_text(json.dumps({"summary": summary, "records": ordered}, indent=2))
        os.replace(partial, out / "blind.json")
        (out / "blind.md").write_text(markdown(summary) + f"\n\nRuntime {summary['runtime_s']:.0f} s.\n")
        return summary

    return save(run_blind(todo, on_trial=save, workers=workers, **options) if todo else [])


def trial_key(trial: Trial | Mapping[str, Any]) -> tuple[str, int, str]:
    """A trial's identity in a run, ``(kind, seed, base method)``, of a :class:`Trial` or of its record (whose
    ``trial_base`` :func:`~jaxheli.benchmark.blind.run_blind` writes)."""
    if isinstance(trial, Trial):
        return trial.kind, trial.seed, trial.base
    return str(trial["kind"]), int(trial["seed"]), str(trial["trial_base"])


def _command(kinds: Sequence[str], seeds: int, **options: Any) -> str:
    """The ``jaxheli blind`` command line of a run (every option spelled out, so it flies the same seeds again)."""
    words = ["jaxheli", "blind", "--kinds", *kinds, "--seeds", str(seeds)]
    for name, value in options.items():
        flag = "--" + name.replace("_", "-")
        if isinstance(value, bool):
            words += [flag] if value else []
        elif value is not None:
            words += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    return shlex.join(words)
