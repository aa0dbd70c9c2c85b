"""The diagnosis's thresholds and the blind check's seed protocol, read from one file (``thresholds.json``
beside this module, or ``$JAXHELI_THRESHOLDS``), the only place the diagnosis and the benchmark take them from.

Each value records the commit that set it and the seeds it was set on. The protocol: design seeds (where rules are
tried), calibration seeds (they set every value here), test seeds (looked at once per rule change, reported, never used
to change a value). A value changed after a test run voids that run's numbers. A seed once flown, in any split, is
spent: :meth:`Protocol.seeds` refuses the seeds of the ledger (:mod:`jaxheli.gap.ledger`).
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

from . import ledger

FILE = Path(__file__).with_name("thresholds.json")
"""The thresholds file shipped with the package."""

ENV = "JAXHELI_THRESHOLDS"
"""Environment variable naming another thresholds file (same layout)."""


@dataclasses.dataclass(frozen=True)
class Protocol:
    """Seed ranges of the blind check: ``design`` and ``calibration`` as inclusive ``(first, last)``, test seeds
    from ``test_from`` on."""

    design: tuple[int, int]
    calibration: tuple[int, int]
    test_from: int

    def seeds(self, split: str, count: int, skip: int = 0, *, refly: bool = False,
              spent: set[int] | None = None) -> list[int]:
        """``count`` seeds of ``split`` (``"design"``, ``"calibration"`` or ``"test"``), from its first after
        ``skip``, none of them spent: a ``ValueError`` names the spent ones, the ledger and where the first run of
        ``count`` unspent seeds of the split starts. ``spent`` defaults to the ledger's seeds
        (:func:`jaxheli.gap.ledger.spent`); ``refly`` lets design seeds be flown again (while a rule is being
        tried on them), never calibration or test seeds."""
        first, last = self._range(split)
        if skip < 0:
            raise ValueError(f"{split} seeds: skip must be >= 0, got {skip}")
        if refly and split != "design":
            raise ValueError(f"{split} seeds are never flown again: only design seeds may be (refly)")
        start = first + skip
        if last is not None and start + count - 1 > last:
            raise ValueError(f"{split} seeds end at {last}: {count} from {start} do not fit")
        seeds = list(range(start, start + count))
        used = set() if refly else (ledger.spent() if spent is None else spent)
        again = [s for s in seeds if s in used]
        if again:
            raise ValueError(f"{split} seeds {ledger.spans_text(again)} are spent (ledger {ledger.path()}); "
                             + self._next(split, count, used))
        return seeds

    def _range(self, split: str) -> tuple[int, int | None]:
        ranges = {"design": self.design, "calibration": self.calibration, "test": (self.test_from, None)}
        if split not in ranges:
            raise ValueError(f"unknown split {split!r}; splits are {tuple(ranges)}")
        return ranges[split]

    def _next(self, split: str, count: int, used: set[int]) -> str:
        """Where the first ``count`` consecutive unspent seeds of ``split`` start, as the seeds to skip."""
        first, last = self._range(split)
        start = first
        while last is None or start + count - 1 <= last:
            clash = [s for s in range(start, start + count) if s in used]
            if not clash:
                more = " (or fly design seeds again, refly)" if split == "design" else ""
                return f"the first {count} unspent start at {start}: skip {start - first} seeds{more}"
            start = max(clash) + 1
        more = "; design seeds may be flown again (refly)" if split == "design" else ""
        return f"no {count} consecutive unspent {split} seeds are left in {first}-{last}{more}"


@dataclasses.dataclass(frozen=True)
class Thresholds:
    """The diagnosis's significance rules (see :mod:`jaxheli.gap.significance` and :mod:`jaxheli.gap.reference`
    for what each does), its predictions' default restart and segment (:mod:`jaxheli.gap.predictor`), the step it
    runs at (:mod:`jaxheli.gap.prepare`) and the blind check's :class:`Protocol`; ``source`` is the file they came
    from."""

    min_shrink: float
    min_z: float
    sig_sigma: float
    effect_sigma: float
    large_shrink: float
    held_out_sigma: float
    lr_p: float
    tie_sigma: float
    settled_pct: float
    start_tie_pct: float
    left_box: float
    recheck: str
    restart: str
    segment_s: float
    sample_s: float
    protocol: Protocol
    source: str


_TYPES = {"float": float, "str": str}
"""How each field of :class:`Thresholds` is read, by its annotation."""


def load(path: str | Path | None = None) -> Thresholds:
    """The thresholds of ``path`` (default ``$JAXHELI_THRESHOLDS``, else :data:`FILE`); a missing or unknown value
    is an error naming the file and the field."""
    path = Path(path or os.environ.get(ENV) or FILE)
    try:
        data = json.loads(path.read_text())
        values = {f.name: _TYPES[f.type](data["thresholds"][f.name]["value"]) for f in dataclasses.fields(Thresholds)
                  if f.name not in ("protocol", "source")}
        p = data["protocol"]
        protocol = Protocol(tuple(p["design_seeds"]), tuple(p["calibration_seeds"]), int(p["test_seeds_from"]))
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: cannot read the thresholds ({err})") from err
    except (KeyError, TypeError) as err:
        raise ValueError(f"{path}: thresholds file lacks or mistypes the field {err}") from err
    return Thresholds(**values, protocol=protocol, source=str(path))


THRESHOLDS = load()
"""The thresholds in force (read once, at import)."""
