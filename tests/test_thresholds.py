"""The thresholds file: every value read from it, errors naming file and field, and no threshold written anywhere
else in the diagnosis or the blind check."""

import ast
import json
from pathlib import Path

import pytest

from jaxheli.gap import thresholds as th

PACKAGE = Path(th.__file__).resolve().parents[1]
NAMES = ("MIN_SHRINK", "MIN_Z", "SIG_SIGMA", "EFFECT_SIGMA", "LARGE_SHRINK", "HELD_OUT_SIGMA", "LR_P", "TIE_SIGMA",
         "SETTLED_PCT", "START_TIE_PCT", "LEFT_BOX", "RESTART", "SEGMENT")


def test_every_value_comes_with_the_commit_and_seeds_that_set_it():
    data = json.loads(th.FILE.read_text())
    for name, entry in data["thresholds"].items():
        assert entry["set_by"] and entry["seeds"] and isinstance(entry["value"], str if name in ("restart", "recheck") else float), name
        assert getattr(th.THRESHOLDS, name) == entry["value"]
    assert th.THRESHOLDS.protocol.test_from > th.THRESHOLDS.protocol.calibration[1]


def test_protocol_seeds_and_their_ranges():
    """The ranges alone, no seed spent (the ledger's refusals: tests/test_ledger.py)."""
    p = th.THRESHOLDS.protocol

    def seeds(*args, **kwargs):
        return p.seeds(*args, spent=set(), **kwargs)

    assert seeds("test", 3) == [p.test_from, p.test_from + 1, p.test_from + 2]
    assert seeds("calibration", 2) == [p.calibration[0], p.calibration[0] + 1]
    with pytest.raises(ValueError, match="design seeds end at 99: 101 from 0 do not fit"):
        seeds("design", 101)
    assert seeds("calibration", 2, skip=40) == [p.calibration[0] + 40, p.calibration[0] + 41]
    assert seeds("test", 1, skip=1000) == [p.test_from + 1000]
    with pytest.raises(ValueError, match="calibration seeds end at"):
        seeds("calibration", 61, skip=40)


def test_another_file_is_read_and_a_missing_field_is_named(tmp_path, monkeypatch):
    data = json.loads(th.FILE.read_text())
    data["thresholds"]["min_shrink"]["value"] = 12.5
    path = tmp_path / "t.json"
    path.write_text(json.dumps(data))
    monkeypatch.setenv(th.ENV, str(path))
    assert th.load().min_shrink == 12.5
    del data["thresholds"]["min_z"]
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"t\.json: thresholds file lacks or mistypes the field 'min_z'"):
        th.load()
    path.write_text("{")
    with pytest.raises(ValueError, match=r"t\.json: cannot read"):
        th.load()


def test_no_threshold_is_written_as_a_number_outside_the_file():
    """``MIN_SHRINK = 10.0`` and the like appear nowhere in the package: each name is bound to the file's value."""
    found = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Assign, ast.AnnAssign)) and isinstance(node.value, ast.Constant):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                found += [f"{path.name}: {t.id}" for t in targets if isinstance(t, ast.Name) and t.id in NAMES]
    assert not found, found
