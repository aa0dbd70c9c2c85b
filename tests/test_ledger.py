"""The ledger of spent seeds: a blind run records every seed it draws (controls included) before it flies, the
protocol refuses spent seeds, the test split is looked at once per rule identity, and the committed ledger holds the
runs before it."""

import json

import pytest

from jaxheli.gap import ledger
from jaxheli.benchmark.blind import _resume, _run
from jaxheli.cli import main
from jaxheli.gap.thresholds import THRESHOLDS

PROTOCOL = THRESHOLDS.protocol


@pytest.fixture(autouse=True)
def tmp_ledger(tmp_path, monkeypatch):
    """A ledger of the test's own (the committed one is never written by the suite)."""
    file = tmp_path / "seed_ledger.jsonl"
    monkeypatch.setenv(ledger.ENV, str(file))
    return file


@pytest.fixture
def flown(monkeypatch):
    """The trials a run hands to the pool, which flies nothing: each is named ``none`` (a right control)."""
    seen = []

    def fake(trials, *, on_trial=None, workers=1, **options):
        seen.extend(trials)
        return [{"kind": t.kind, "seed": t.seed, "top": "none", "correct": t.kind == "none", "detectable": True,
                 "base": {"method": t.base}, "trial_base": t.base} for t in trials]

    monkeypatch.setattr(_run, "run_blind", fake)
    return seen


def test_a_run_records_every_seed_it_flies_controls_included(tmp_ledger, tmp_path, flown):
    summary = _run.run_benchmark(["input_delay", "none"], 2, tmp_path / "out", split="design", skip_seeds=30,
                                 truth="library", duration=12.0)
    (entry,) = ledger.read(tmp_ledger)
    assert entry.seeds == {"input_delay": [(30, 31)], "none": [(30, 33)]}
    assert entry.numbers() == {t.seed for t in flown} == {30, 31, 32, 33}
    assert (entry.split, entry.truth, entry.look) == ("design", "library", False)
    assert entry.rules == ledger.rule_id({k: v for k, v in summary["settings"]["thresholds"].items() if k != "file"})
    assert entry.command.startswith("jaxheli blind --kinds input_delay none --seeds 2 --truth library --split design "
                                    "--control-seeds 4 --skip-seeds 30") and "--duration 12" in entry.command
    assert entry.date and summary["settings"]["ledger"]["entry"] == entry.to_json()


def test_a_spent_seed_is_refused_with_where_the_unspent_ones_start(tmp_ledger, tmp_path, flown):
    """Through the command line: the second run of the same seeds is refused in one line naming the seeds, the
    ledger and the ``--skip-seeds`` of the first unspent run; the ledger is unchanged by the refusal; ``--refly-design``
    flies design seeds again (recorded again)."""
    argv = ["blind", "--kinds", "input_delay", "none", "--seeds", "2", "--skip-seeds", "30", "--iwo-seeds", "0",
            "--out", str(tmp_path / "out")]
    assert main(argv) == 0
    with pytest.raises(ValueError) as err:
        _run.run_benchmark(["none"], 1, tmp_path / "again", control_seeds=3, skip_seeds=31)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"design seeds 31-33 are spent (ledger {tmp_ledger}); ")
    assert "the first 3 unspent start at 0: skip 0 seeds" in message
    assert main(argv) == 2 and len(ledger.read(tmp_ledger)) == 1
    assert main([*argv, "--refly-design"]) == 0 and len(ledger.read(tmp_ledger)) == 2


def test_the_protocol_refuses_spent_seeds_and_names_the_next_unspent_run():
    spent = set(range(1000, 1040)) | {1045}
    assert PROTOCOL.seeds("test", 5, 40, spent=spent) == [1040, 1041, 1042, 1043, 1044]
    with pytest.raises(ValueError, match=r"test seeds 1000-1009 are spent \(ledger .*\); the first 10 unspent start "
                                         r"at 1046: skip 46 seeds$"):
        PROTOCOL.seeds("test", 10, spent=spent)
    with pytest.raises(ValueError, match="the first 5 unspent start at 1040: skip 40 seeds"):
        PROTOCOL.seeds("test", 5, 10, spent=spent)
    first, last = PROTOCOL.calibration
    with pytest.raises(ValueError, match=f"no 2 consecutive unspent calibration seeds are left in {first}-{last}$"):
        PROTOCOL.seeds("calibration", 2, spent=set(range(first, last + 1)))
    assert PROTOCOL.seeds("design", 2, spent={0, 1}, refly=True) == [0, 1]
    with pytest.raises(ValueError, match="test seeds are never flown again"):
        PROTOCOL.seeds("test", 2, refly=True)


def test_the_test_split_is_looked_at_once_per_rule_identity_and_simulator(tmp_ledger, tmp_path, flown):
    _run.run_benchmark(["none"], 1, tmp_path / "a", split="test", control_seeds=2, truth="library")
    (look,) = ledger.read(tmp_ledger)
    assert look.look and look.seeds == {"none": [(PROTOCOL.test_from, PROTOCOL.test_from + 1)]}
    with pytest.raises(ValueError, match=r"test split: the library simulator was looked at under these rules "
                                         r"\(sha256:[0-9a-f]{16}\) on .*one test look per rule change"):
        _run.run_benchmark(["none"], 1, tmp_path / "b", split="test", control_seeds=2, skip_seeds=10)
    assert len(ledger.read(tmp_ledger)) == 1
    _run.run_benchmark(["dryden"], 1, tmp_path / "c", split="test", skip_seeds=10, truth="independent")
    assert [e.truth for e in ledger.read(tmp_ledger)] == ["library", "independent"]


def test_the_rule_identity_follows_the_threshold_values_not_the_files_prose():
    values = {"min_shrink": 5.0, "restart": "segment"}
    assert ledger.rule_id(values) == ledger.rule_id(dict(reversed(values.items())))
    assert ledger.rule_id(values) != ledger.rule_id({**values, "min_shrink": 5.5})


def test_a_ledger_line_that_does_not_parse_is_named(tmp_ledger):
    tmp_ledger.write_text('{"seeds": {"none": [[1, 2]]}, "split": "design"}\n')
    with pytest.raises(ValueError, match=r"seed_ledger\.jsonl:1: not a seed-ledger line"):
        ledger.spent()


def test_the_committed_ledger_holds_the_runs_before_it():
    """Design, calibration and test seeds flown before the ledger, read from docs/blind_history.md, README.md and
    thresholds.json (each line names its source), come first; the whole calibration range is spent. Every line after
    them is a run ``jaxheli blind`` appended: its rules, commit and command, no source."""
    entries = ledger.read(ledger.FILE)
    assert [json.loads(line) for line in ledger.FILE.read_text().splitlines()] == [e.to_json() for e in entries]
    before = [e for e in entries if e.source]
    since = entries[len(before):]
    assert before and all(e.rules is None for e in before)
    assert all(not e.source and e.rules and e.commit and e.command.startswith("jaxheli blind") for e in since)
    spent = {s for e in before for s in e.numbers()}
    for first, last in [(0, 29), (40, 63), (70, 87), (100, 199), (1000, 1039), (2000, 2039), (3000, 3039),
                        (4000, 4034), (5000, 5279), (6000, 6159)]:
        assert set(range(first, last + 1)) <= spent, (first, last)
    assert ledger.spans_text(spent) == ("0-29, 40-63, 70-87, 100-199, 1000-1039, 2000-2039, 3000-3039, 4000-4034, "
                                        "5000-5279, 6000-6159")
    assert {e.split for e in entries} == {"design", "calibration", "test"}
    assert all(e.look == (e.split == "test") for e in entries)
    with pytest.raises(ValueError, match="the first 20 unspent start at 1040: skip 40 seeds"):
        PROTOCOL.seeds("test", 20, spent=spent)
    with pytest.raises(ValueError, match="the first 10 unspent start at 30: skip 30 seeds"):
        PROTOCOL.seeds("design", 10, spent=spent)


def _stop_early(out, keep):
    """Cut the record ``OUT/blind.json`` back to its first ``keep`` trials, as a run stopped there leaves it."""
    file = out / "blind.json"
    data = json.loads(file.read_text())
    data["records"] = data["records"][:keep]
    data["summary"]["complete"] = False
    file.write_text(json.dumps(data))
    return file


def test_a_stopped_run_resumes_flying_only_the_trials_it_lacks(tmp_ledger, tmp_path, flown, monkeypatch):
    """Resumed (through the command line), a run flies the trials its record lacks, keeps the ones it holds, in
    the order they fly, records the resumption and spends no seed again; a complete run is not resumed."""
    monkeypatch.setattr(_resume, "_changed_since", lambda commit: [])
    out = tmp_path / "out"
    full = _run.run_benchmark(["input_delay", "none"], 2, out, split="design", skip_seeds=30, duration=12.0)
    records = json.loads((out / "blind.json").read_text())["records"]
    file = _stop_early(out, 3)
    flown.clear()
    assert main(["blind", "--resume", str(file), "--workers", "1"]) == 0
    assert [(t.kind, t.seed) for t in flown] == [(r["kind"], r["seed"]) for r in records[3:]]
    data = json.loads(file.read_text())
    assert data["records"] == records and data["summary"]["complete"]
    (resumed,) = data["summary"]["settings"]["resumed"]
    assert resumed["records"] == 3 and resumed["workers"] == 1
    assert data["summary"]["kinds"] == full["kinds"] and len(ledger.read(tmp_ledger)) == 1
    with pytest.raises(ValueError, match="the run is complete .*nothing to resume"):
        _resume.resume_benchmark(file)
    with pytest.raises(SystemExit, match="--seeds, --out not read: a resumed run keeps the settings its record holds"):
        main(["blind", "--resume", str(file), "--seeds", "3", "--out", str(tmp_path)])


def test_a_run_is_resumed_only_with_its_seeds_rules_and_code(tmp_ledger, tmp_path, flown, monkeypatch):
    out = tmp_path / "out"
    _run.run_benchmark(["none"], 1, out, control_seeds=3, skip_seeds=30, truth="library")
    file = _stop_early(out, 1)
    monkeypatch.setattr(_resume, "_changed_since", lambda commit: ["jaxheli/gap/verdict.py"])
    with pytest.raises(ValueError, match="differs from .*in jaxheli/gap/verdict.py; a run is resumed with the code"):
        _resume.resume_benchmark(file)
    monkeypatch.setattr(_resume, "_changed_since", lambda commit: [])
    monkeypatch.setattr(ledger, "rule_id", lambda thresholds: "sha256:0000000000000000")
    with pytest.raises(ValueError, match=r"started under the rules sha256:[0-9a-f]{16}, these are sha256:0{16}"):
        _resume.resume_benchmark(file)
    monkeypatch.undo()
    monkeypatch.setenv(ledger.ENV, str(tmp_path / "other.jsonl"))
    with pytest.raises(ValueError, match="seeds \\(30-32, .*\\) are not in the seed ledger"):
        _resume.resume_benchmark(file)
    assert not flown[3:]


def test_records_written_before_the_trial_base_was_recorded_resume_when_the_run_has_one_base(tmp_ledger, tmp_path,
                                                                                           flown, monkeypatch):
    monkeypatch.setattr(_resume, "_changed_since", lambda commit: [])
    for iwo_seeds, ok in ((0, True), (1, False)):
        out = tmp_path / f"iwo{iwo_seeds}"
        _run.run_benchmark(["none"], 1, out, control_seeds=2, skip_seeds=40 + 10 * iwo_seeds, iwo_seeds=iwo_seeds)
        file = _stop_early(out, 1)
        data = json.loads(file.read_text())
        del data["records"][0]["trial_base"]
        file.write_text(json.dumps(data))
        if ok:
            assert _resume.resume_benchmark(file)["complete"]
        else:
            with pytest.raises(ValueError, match="does not say its trial's base method, and the run has two"):
                _resume.resume_benchmark(file)
