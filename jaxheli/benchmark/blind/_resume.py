"""A blind run stopped before its last trial, resumed: the trials its ``blind.json`` does not hold are flown under
the same settings, rules and seeds (already in the seed ledger), and the record grows in place."""

from __future__ import annotations

import inspect
import json
import subprocess
from pathlib import Path
from typing import Any

from ...gap import ledger
from ._run import fly, thresholds_in_force, trial_list
from ._trial import run_trial

_TRIAL_OPTIONS = tuple(n for n in inspect.signature(run_trial).parameters if n not in ("kind", "seed", "base"))

_FREE = ("jaxheli/cli/", "jaxheli/benchmark/blind/")
"""Package folders a resumed run may differ in from the commit that started it: the command line and the blind
runner (how trials are dispatched and recorded); everything else (the rules, the truth simulator, the fits) must be
byte-identical."""


def resume_benchmark(blind_json: str | Path, workers: int | None = None) -> dict[str, Any]:
    """Resume the blind run whose record is ``blind_json`` (``OUT/blind.json`` of :func:`run_benchmark`): fly the
    trials it does not hold, in ``workers`` processes (default the run's), and rewrite ``OUT/blind.json`` and
    ``OUT/blind.md`` after each; the summary. Refused (``ValueError`` naming the file and the reason) when the run
    is complete, its seeds are not in the seed ledger as it recorded them, the rule identity
    (:func:`~jaxheli.gap.ledger.rule_id`) is not the one it started under, or the package differs from the commit
    that started it outside the command line and the blind runner (:data:`_FREE`; checked where git is at hand).
    Each resumption is recorded in the settings (``resumed``: date, commit, records held, workers)."""
    blind_json = Path(blind_json)
    try:
        data = json.loads(blind_json.read_text())
        summary, records = data["summary"], list(data["records"])
        settings = dict(summary["settings"])
        entry = ledger.Entry.from_json(settings["ledger"]["entry"])
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{blind_json}: not the record of a blind run ({err!r})") from err
    if summary.get("complete"):
        raise ValueError(f"{blind_json}: the run is complete ({len(records)} trials); nothing to resume")
    if entry not in ledger.read():
        raise ValueError(f"{blind_json}: its seeds ({ledger.spans_text(entry.numbers())}, {entry.date}) are not in "
                         f"the seed ledger {ledger.path()}; a run is resumed only where its seeds were recorded")
    rules = ledger.rule_id(thresholds_in_force())
    if rules != entry.rules:
        raise ValueError(f"{blind_json}: the run started under the rules {entry.rules}, these are {rules}; a run "
                         "is resumed under its own rules only")
    changed = _changed_since(entry.commit)
    if changed:
        raise ValueError(f"{blind_json}: the package differs from {entry.commit}, which started the run, in "
                         f"{', '.join(changed)}; a run is resumed with the code that started it")
    base = str(settings["base"])
    for r in records:
        if "trial_base" not in r:
            if settings.get("iwo_seeds"):
                raise ValueError(f"{blind_json}: record {r.get('kind')}, seed {r.get('seed')} does not say its "
                                 "trial's base method, and the run has two")
            r["trial_base"] = base
    drawn = {k: sorted(s for a, b in spans for s in range(a, b + 1)) for k, spans in entry.seeds.items()}
    trials = trial_list(settings["kinds"], drawn, base, int(settings.get("iwo_seeds", 0)))
    workers = int(settings.get("workers", 1)) if workers is None else workers
    settings["resumed"] = [*settings.get("resumed", []),
                           {"date": ledger.now(), "commit": ledger.head_commit(), "records": len(records),
                            "workers": workers}]
    options = {k: settings[k] for k in _TRIAL_OPTIONS if k in settings}
    return fly(trials, blind_json.parent, settings, records, workers=workers,
               prior_s=float(summary.get("runtime_s", 0.0)), **options)


def _changed_since(commit: str | None) -> list[str]:
    """Files of the package that differ between ``commit`` and the working tree, outside :data:`_FREE`; empty
    without git or without a commit to compare with."""
    if commit is None:
        return []
    try:
        out = subprocess.run(["git", "diff", "--name-only", commit, "--", "jaxheli"], cwd=ledger.PACKAGE.parent,
                             capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return []
    if out.returncode != 0:
        return []
    return [f for f in out.stdout.split() if f.endswith(".py") and not f.startswith(_FREE)]
