"""``jaxheli evaluate | identify | diagnose`` on every shared .px4log: u and v never move in those logs, so they
are left out with a one-line note instead of the Pearson cost failing on a constant channel."""

import json

import numpy as np
import pytest

from jaxheli.cli import main

LOGS = ("2016-09-08/09_16_59.px4log", "2016-08-09/13_25_39.px4log", "sess006/log001.px4log")


def _run(capsys, argv):
    capsys.readouterr()
    rc = main(argv)
    captured = capsys.readouterr()
    assert rc == 0 and "Traceback" not in captured.err, captured.err
    return captured


@pytest.mark.parametrize("name", LOGS)
def test_evaluate_every_shared_px4log(shared_data, capsys, name):
    captured = _run(capsys, ["evaluate", "--model", "table2", "--data", str(shared_data / "px4logs" / name)])
    notes = [line for line in captured.err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "u, v constant: left out of the default channel set" in notes[0]
    assert "cost (paper Eq. 7)" in captured.out


@pytest.mark.parametrize("name", LOGS)
def test_identify_every_shared_px4log(shared_data, capsys, tmp_path, name):
    _run(capsys, ["identify", "--method", "iwo", "--iterations", "1", "--train", str(shared_data / "px4logs" / name),
                  "--out", str(tmp_path)])
    assert (tmp_path / "result.json").is_file()


def test_diagnose_on_shared_px4logs(shared_data, capsys, tmp_path):
    logs = shared_data / "px4logs"
    _run(capsys, ["diagnose", "--model", "table2", "--train", str(logs / LOGS[2]), "--validate", str(logs / LOGS[1]),
                  "--effects", "input_delay", "--max-steps", "2", "--track", "1", "--top", "1", "--frozen-base", "--out",
                  str(tmp_path)])
    diagnosis = json.loads((tmp_path / "diagnosis.json").read_text())
    assert "u" not in diagnosis["outputs"] and "v" not in diagnosis["outputs"]  # constant in these logs: left out
    assert [e["effect"] for e in diagnosis["ranking"]] == ["input_delay"]
    assert np.isfinite(diagnosis["ranking"][0]["shrink_pct"])
