"""The ledger of spent seeds: every seed the blind check has flown, one JSON line per run, appended by ``jaxheli blind``
before it flies (``seed_ledger.jsonl`` beside this module, or ``$JAXHELI_LEDGER``).

The rule it keeps: a benchmark's rules are set on design seeds and reported on test seeds that never changed a rule;
a seed once flown, in any split, is spent. A trial's random streams and its perturbed truth depend on the seed alone
(:func:`~jaxheli.benchmark.blind.scenario`), so the seed *number* is spent, whatever the kind, split or simulator
that flew it. :meth:`jaxheli.gap.thresholds.Protocol.seeds` refuses spent seeds (design seeds may be flown again with
an explicit flag, calibration and test seeds never), and a test look is taken once per rule identity
(:func:`rule_id`) and truth simulator (:func:`refuse_second_look`).

Each line is an :class:`Entry`. A run records every seed it draws, controls included, when it starts: a run stopped
early has spent them all. The first lines are the runs before the ledger, read from ``docs/blind_history.md``,
``README.md`` and ``jaxheli/gap/thresholds.json`` (their ``source`` says where); their rule identity is unknown.
This module reads no other part of the package (the thresholds module imports it).
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import json
import os
import subprocess
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

FILE = Path(__file__).with_name("seed_ledger.jsonl")
"""The ledger kept in the repository (and shipped with the package)."""

ENV = "JAXHELI_LEDGER"
"""Environment variable naming another ledger file (tests point it at a temporary one)."""

PACKAGE = Path(__file__).resolve().parents[1]

RULE_CODE: tuple[str, ...] = ("gap", "effects")
"""Package folders whose code makes the diagnosis's rules (with the threshold values): :func:`rule_id` hashes them."""


def path() -> Path:
    """The ledger in force: ``$JAXHELI_LEDGER``, else :data:`FILE`."""
    return Path(os.environ.get(ENV) or FILE)


@dataclasses.dataclass(frozen=True)
class Entry:
    """One run's seeds: ``seeds`` maps each kind (or, for a run before the ledger, a label) to inclusive ``(first,
    last)`` ranges; ``split``, ``truth`` the simulator, ``look`` whether it was a look at the test split, ``rules``
    the :func:`rule_id` it ran under (``None`` before the ledger), ``commit`` the repository's ``HEAD`` (``None``
    without git), ``date`` (UTC), ``command`` that flew it, ``source`` where a run before the ledger is documented."""

    seeds: dict[str, list[tuple[int, int]]]
    split: str
    truth: str
    date: str
    command: str
    look: bool = False
    rules: str | None = None
    commit: str | None = None
    source: str | None = None

    def numbers(self) -> set[int]:
        """Every seed number the run spent."""
        return {s for spans in self.seeds.values() for a, b in spans for s in range(a, b + 1)}

    def to_json(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["seeds"] = {k: [list(r) for r in v] for k, v in self.seeds.items()}
        return {k: v for k, v in data.items() if v is not None}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Entry:
        seeds = {str(k): [(int(a), int(b)) for a, b in v] for k, v in data["seeds"].items()}
        return cls(seeds, str(data["split"]), str(data["truth"]), str(data["date"]), str(data["command"]),
                   bool(data.get("look", False)), data.get("rules"), data.get("commit"), data.get("source"))


def spans(seeds: Iterable[int]) -> list[tuple[int, int]]:
    """``seeds`` as sorted inclusive ``(first, last)`` runs of consecutive numbers."""
    out: list[tuple[int, int]] = []
    for s in sorted(set(seeds)):
        if out and s == out[-1][1] + 1:
            out[-1] = (out[-1][0], s)
        else:
            out.append((s, s))
    return out


def spans_text(seeds: Iterable[int]) -> str:
    """``seeds`` as ``"1000-1019, 1030"``."""
    return ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in spans(seeds))


def read(file: str | Path | None = None) -> list[Entry]:
    """The entries of ``file`` (default :func:`path`); a missing file is an empty ledger, a line that does not parse
    an error naming the file and line."""
    file = Path(file) if file is not None else path()
    if not file.exists():
        return []
    entries = []
    for n, line in enumerate(file.read_text().splitlines(), 1):
        if line.strip():
            try:
                entries.append(Entry.from_json(json.loads(line)))
            except (ValueError, KeyError, TypeError) as err:
                raise ValueError(f"{file}:{n}: not a seed-ledger line ({err!r})") from err
    return entries


def spent(file: str | Path | None = None) -> set[int]:
    """Every seed number the ledger ``file`` (default :func:`path`) holds."""
    return {s for e in read(file) for s in e.numbers()}


def append(entry: Entry, file: str | Path | None = None) -> Path:
    """Append ``entry`` as one line to ``file`` (default :func:`path`); the file written."""
    file = Path(file) if file is not None else path()
    file.parent.mkdir(parents=True, exist_ok=True)
    with file.open("a") as f:
        f.write(json.dumps(entry.to_json(), separators=(", ", ": ")) + "\n")
    return file


def rule_id(thresholds: Mapping[str, Any]) -> str:
    """The identity of the rules a run is scored under, without git (a clean copy gives the same): SHA-256 of the
    threshold values in force (``thresholds``, name to value; not the file's prose or its record of test runs, so
    writing a run down changes nothing) and of every ``.py`` file under :data:`RULE_CODE` (path and bytes), as
    ``"sha256:"`` and its first 16 hex digits. Any change to that code, a docstring's too, is a new identity."""
    digest = hashlib.sha256(json.dumps(dict(sorted(thresholds.items())), sort_keys=True).encode())
    for folder in RULE_CODE:
        for file in sorted((PACKAGE / folder).rglob("*.py")):
            digest.update(file.relative_to(PACKAGE).as_posix().encode() + b"\0" + file.read_bytes() + b"\0")
    return "sha256:" + digest.hexdigest()[:16]


def head_commit() -> str | None:
    """``git rev-parse HEAD`` of the package's checkout, or ``None`` (no git, not a checkout)."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=PACKAGE, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip() or None


def now() -> str:
    """The time, UTC, to the second (ISO 8601)."""
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def refuse_second_look(truth: str, rules: str, file: str | Path | None = None) -> None:
    """Refuse a second look at the test split: a ``ValueError`` naming the first when the ledger ``file`` (default
    :func:`path`) holds a test look of the ``truth`` simulator under the rule identity ``rules``."""
    file = Path(file) if file is not None else path()
    for n, e in enumerate(read(file), 1):
        if e.look and e.truth == truth and e.rules == rules:
            raise ValueError(f"test split: the {truth} simulator was looked at under these rules ({rules}) on "
                             f"{e.date}, seeds {spans_text(e.numbers())} ({file}, entry {n}); one test look per "
                             "rule change: change a rule, and record the look in thresholds.json, before another")
