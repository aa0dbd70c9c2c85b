"""Time-domain verification (jaxheli.verify) against an independent numpy/scipy reference; its CLI."""

import json

import numpy as np
import pytest
import scipy.signal

from jaxheli import TABLE2, build_ab, piloted_flight, trim
from jaxheli.model import PARAM_NAMES, output_indices
from jaxheli.verify import save_verification, verify

MODEL = TABLE2.copy()
MODEL[PARAM_NAMES.index("Lb")] *= 1.5
MODEL[PARAM_NAMES.index("Ma")] *= 0.6
MODEL[PARAM_NAMES.index("Nr")] *= 0.5
"""A known model, not the flight's truth (Table 2), so every score is far from perfect."""
OFFSETS = {"u": 0.3, "v": -0.2, "p": 0.01, "q": -0.02, "phi": 0.05, "theta": -0.03, "w": 0.1, "r": 0.02}
"""Sensor offsets added to the synthetic flight, which each run's bias must absorb."""


def _offset_flight(noise: float):
    f = trim(piloted_flight(duration=30.0, seed=3, noise=noise), 10.0, 20.5)  # 10.5 s inside the excitation
    return f.replace(outputs=f.outputs + np.array([OFFSETS[c] for c in f.output_names]))


@pytest.fixture(scope="module")
def flight():
    return _offset_flight(1.0)


def _reference_run(A, B, C, dt, inputs, meas):
    """One run with numpy/scipy only: ZOH by scipy.signal.cont2discrete, the response from rest by dlsim, the
    free responses C Ad^m e_i by explicit matrix powers, x0 and bias by np.linalg.lstsq."""
    Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, C, np.zeros((C.shape[0], B.shape[1]))), dt, method="zoh")
    n, k = meas.shape
    _, forced, _ = scipy.signal.dlsim((Ad, Bd, C, np.zeros((k, B.shape[1])), dt), inputs)
    free = np.stack([C @ np.linalg.matrix_power(Ad, m) for m in range(n)])  # [n, k, 13]
    design = np.concatenate([free.reshape(n * k, -1), np.tile(np.eye(k), (n, 1))], axis=1)
    solution, *_ = np.linalg.lstsq(design, (meas - forced).ravel(), rcond=None)
    return forced + (design @ solution).reshape(n, k), solution[:13], solution[13:]


def _reference_scores(y, m, spread):
    """TIC, J_rms (W = 1/spread^2), Pearson, fit % per channel, and the overall values, in numpy."""
    e = y - m
    rms = lambda x: np.sqrt(np.mean(x**2, axis=0))  # noqa: E731
    tic = rms(e) / (rms(y) + rms(m))
    j = rms(e) / spread
    rho = np.array([np.corrcoef(y[:, i], m[:, i])[0, 1] for i in range(m.shape[1])])
    fit = 100 * (1 - np.linalg.norm(e, axis=0) / np.linalg.norm(m - m.mean(axis=0), axis=0))
    return {"tic": (tic, tic.mean()), "j_rms": (j, np.sqrt(np.mean(e**2 / spread**2))),
            "pearson": (rho, rho.mean()), "fit_percent": (fit, fit.mean())}


def test_runs_match_an_independent_numpy_reference(flight):
    v = verify(MODEL, flight, run_length=5.0)
    chans = v.channels
    assert chans == flight.output_names and len(v.runs) == 2  # 10.5 s: runs 0-5 s and 5-10 s, 0.5 s left out
    assert any("left out" in n for n in v.notes)
    A, B = (np.asarray(x) for x in build_ab(MODEL))
    C = np.eye(13)[output_indices(chans)]
    meas_all = flight.select(chans).outputs
    spread = meas_all.std(axis=0)
    ys, ms = [], []
    for j, run in enumerate(v.runs):
        rows = slice(500 * j, 500 * j + 501)
        m = meas_all[rows]
        y, x0, bias = _reference_run(A, B, C, flight.dt, flight.inputs[rows], m)
        assert run.start_s == pytest.approx(flight.time[500 * j]) and run.measured.shape == m.shape
        np.testing.assert_allclose(run.simulated, y, rtol=0, atol=1e-8 * np.abs(m).max())
        np.testing.assert_allclose(np.concatenate([run.x0, run.bias]), np.concatenate([x0, bias]), rtol=1e-6,
                                   atol=1e-8)
        for key, (per_channel, overall) in _reference_scores(y, m, spread).items():
            np.testing.assert_allclose([run.scores[key][c] for c in chans], per_channel, rtol=1e-8, atol=1e-8)
            assert run.scores[key]["overall"] == pytest.approx(overall, rel=1e-8, abs=1e-8)
        ys.append(y)
        ms.append(m)
    for key, (per_channel, overall) in _reference_scores(np.concatenate(ys), np.concatenate(ms), spread).items():
        np.testing.assert_allclose([v.pooled[key][c] for c in chans], per_channel, rtol=1e-8, atol=1e-8)
        assert v.pooled[key]["overall"] == pytest.approx(overall, rel=1e-8, abs=1e-8)


def test_the_true_model_on_a_noise_free_flight_is_exact_and_its_bias_the_offsets():
    flight = _offset_flight(0.0)
    v = verify(TABLE2, flight, run_length=5.0)
    for run in v.runs:
        np.testing.assert_allclose(run.bias, [OFFSETS[c] for c in v.channels], atol=1e-6)
        assert max(run.scores["tic"].values()) < 1e-6 and min(run.scores["fit_percent"].values()) > 99.999
    assert v.pooled["j_rms"]["overall"] < 1e-6 and not v.notes[1:]


def test_whole_window_of_a_fast_diverging_model_is_flagged(flight):
    diverging = TABLE2.copy()
    diverging[PARAM_NAMES.index("Zw")] = 0.8  # heave mode doubles in 0.87 s
    v = verify(diverging, flight, run_length=None)
    assert len(v.runs) == 1 and v.run_length is None
    assert any("doubles every 0.866 s" in n and "meaningless" in n for n in v.notes)


def test_cli_writes_json_csv_and_a_png_per_run(tmp_path, flight, capsys):
    from jaxheli.cli import main
    from jaxheli.io import save

    data = save(flight, tmp_path / "flight.npz")
    assert main(["verify", "--model", "table2", "--data", str(data), "--run-length", "5", "--out",
                 str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    assert "TIC (<= 0.3)" in printed and "J_rms (<= 2)" in printed and "yaw-heave (heave)" in printed
    content = json.loads((tmp_path / "out" / "verification.json").read_text())
    assert content["model"] == "table2" and content["modes"][0]["name"] == "yaw-heave (heave)"
    assert len(content["verifications"][0]["runs"]) == 2
    rows = (tmp_path / "out" / "verification.csv").read_text().splitlines()
    assert rows[0].startswith("source,run_length_s,run,") and len(rows) == 1 + 3 * (8 + 1)
    assert len(list((tmp_path / "out").glob("run_1_5s_*.png"))) == 2


def test_save_verification_writes_what_verify_found(tmp_path, flight):
    v = verify(MODEL, flight, run_length=10.0)
    files = save_verification([v], "model", tmp_path)
    assert [f.name for f in files] == ["verification.json", "verification.csv", "run_1_10s_001.png"]
