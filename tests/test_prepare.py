"""``jaxheli prepare``: the preparation chain from the command line, its provenance in the NPZ, and the paper
comparison's training flight reproduced exactly (then read by ``identify``)."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxheli.cli import main
from jaxheli.data.flight import FlightData
from jaxheli.gap.prepare import SAMPLE_S, at_step
from jaxheli.io import load, save_npz
from jaxheli.synth.piloted import piloted_flight

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from paper_comparison import training_flight  # noqa: E402


def _same_flight(a, b):
    assert a.output_names == b.output_names
    for field in ("time", "inputs", "outputs"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def _tones(dt, seconds=20.0):
    """A flight of step ``dt`` (s) whose p carries 1.0 at 1 Hz plus 1.0 at 12 Hz, inputs a 0.5-Hz sine."""
    t = np.arange(0.0, seconds, dt)
    p = np.sin(2 * np.pi * 1.0 * t) + np.sin(2 * np.pi * 12.0 * t)
    inputs = np.tile(np.sin(2 * np.pi * 0.5 * t)[:, None], (1, 4))
    return FlightData(t, inputs, np.stack([p, 0.1 * t], axis=1), ("p", "phi"), "tones.npz")


def test_the_diagnosis_step_keeps_the_band_and_drops_what_would_alias():
    """A 50-Hz flight comes to the thresholds' 20-Hz step: the 1-Hz tone in phase at 95-100 % of its amplitude,
    the 12-Hz tone (it would alias to 8 Hz) gone, the ramp and the inputs kept; a flight at the step is left
    as it is."""
    assert SAMPLE_S == 0.05
    coarse = _tones(SAMPLE_S)
    assert at_step(coarse) is coarse and at_step(_tones(0.1)).dt == 0.1 and at_step(_tones(0.02), None).dt == 0.02
    fine = at_step(_tones(0.02))
    assert fine.dt == pytest.approx(SAMPLE_S) and fine.time[0] == 0.0
    assert [s["step"] for s in fine.metadata["preprocessing"]] == ["lowpass", "resample"]
    mid = slice(40, -40)  # away from the filter's ends
    t = fine.time[mid]
    basis = np.stack([np.sin(2 * np.pi * t), np.cos(2 * np.pi * t), np.sin(2 * np.pi * 8.0 * t),
                      np.cos(2 * np.pi * 8.0 * t)], axis=1)
    (s1, c1, s8, c8), *_ = np.linalg.lstsq(basis, fine.outputs[mid, 0], rcond=None)
    assert 0.95 < s1 <= 1.0 and abs(c1) < 1e-3 and np.hypot(s8, c8) < 0.05
    np.testing.assert_allclose(fine.outputs[mid, 1], 0.1 * t, atol=1e-6)
    np.testing.assert_allclose(fine.inputs[mid], np.sin(2 * np.pi * 0.5 * t)[:, None] * np.ones(4), atol=1e-3)


def test_prepare_and_identify_reproduce_the_paper_training_flight(shared_data, tmp_path):
    source = shared_data / "trex550" / "Data_graphready.mat"
    prepared = tmp_path / "flight_a.npz"
    assert main(["prepare", "--data", str(source), "--trim", "50", "--correct", "--lowpass", "3", "--out",
                 str(prepared)]) == 0
    expected, findings = training_flight(load(source))
    flight = load(prepared)
    _same_flight(flight, expected)
    steps = [s["step"] for s in flight.metadata["preprocessing"]]
    assert steps == [s["step"] for s in expected.metadata["preprocessing"]]
    assert [f["kind"] for f in flight.metadata["consistency"]] == [f.kind for f in findings]
    out = tmp_path / "fit"
    assert main(["identify", "--method", "iwo", "--iterations", "1", "--train", str(prepared), "--outputs",
                 "p,q,phi,theta", "--out", str(out)]) == 0
    _same_flight(load(out / "train_flight.npz"), expected)
    recorded = json.loads((out / "result.json").read_text())["provenance"]["train"]["preprocessing"]
    assert [s["step"] for s in recorded] == steps == ["trim", "consistency.correct", "lowpass"]


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    path = tmp_path_factory.mktemp("prepare") / "raw.npz"
    save_npz(piloted_flight(duration=30.0, dt=0.02, seed=4), path)
    return path


def test_prepare_steps_in_order_and_recorded(raw, tmp_path, capsys):
    out = tmp_path / "ready.npz"
    assert main(["prepare", "--data", f"{raw}:1-29", "--trim", "5", "--check", "--lowpass", "5",
                 "--resample", "0.04", "--out", str(out)]) == 0
    flight = load(out)
    steps = flight.metadata["preprocessing"]
    assert [s["step"] for s in steps] == ["trim", "lowpass", "resample"]
    assert steps[0]["start"] == 1.0 and steps[0]["stop"] == 29.0 and steps[0]["drop_samples"] == [5, 5]
    assert flight.dt == pytest.approx(0.04) and flight.time[0] == pytest.approx(1.1)
    assert isinstance(flight.metadata["consistency"], list)
    assert "steps: trim, lowpass, resample" in capsys.readouterr().out


@pytest.mark.parametrize(("window", "argv", "needle"), [
    (":9-1", [], "the window's end 1.0 s must come after its start 9.0 s"),
    ("", ["--trim", "-1"], "--trim: must be >= 0"),
    ("", ["--lowpass", "1000"], "cutoff_hz"),
])
def test_prepare_errors_are_one_line(raw, tmp_path, capsys, window, argv, needle):
    capsys.readouterr()
    assert main(["prepare", "--data", f"{raw}{window}", *argv, "--out", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and needle in err
