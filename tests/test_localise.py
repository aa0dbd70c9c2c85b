"""Gap localisation and frequency responses against independent references (scipy, analytic cases, injected
residuals of known structure)."""

import argparse
import json

import numpy as np
import pytest
import scipy.signal as ss

import jaxheli
from jaxheli.cost import nmse
from jaxheli.model import output_matrix
from jaxheli.spectra import estimate_frequency_response, model_frequency_response
from jaxheli.gap.localisation_record import Localisation
from jaxheli.gap.localise import localise
from jaxheli.cli.gap import add_localise_parser as add_parser

DT = 0.01
N = 4000


def _sticks(seed: int, n: int = N, envelope: np.ndarray | None = None) -> np.ndarray:
    """Four independent band-limited stick records (0-4 Hz), optionally scaled by an envelope."""
    rng = np.random.default_rng(seed)
    sos = ss.butter(4, 4.0, fs=1 / DT, output="sos")
    u = ss.sosfilt(sos, rng.normal(size=(n, 4)), axis=0)
    u /= u.std(axis=0)
    return 0.2 * u * (1.0 if envelope is None else envelope[:, None])


def _flight(inputs: np.ndarray, measured: np.ndarray, names=("p", "q")) -> jaxheli.FlightData:
    return jaxheli.FlightData(DT * np.arange(inputs.shape[0]), inputs, measured, names, source="test")


def _noise(seed: int, shape) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=shape)


def test_welch_output_power_matches_scipy():
    u, y = _sticks(0)[:, :2], _noise(1, (N, 2))
    est = estimate_frequency_response(u, y, DT, segment_seconds=4.0, overlap=0.5)
    f, ref = ss.welch(y, fs=1 / DT, nperseg=400, noverlap=200, axis=0)
    np.testing.assert_allclose(np.asarray(est.freq), f[1:], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(est.output_power), ref[1:], rtol=1e-9)


def test_mimo_response_of_known_discrete_system_with_correlated_inputs():
    """y = G1 u1 + G2 u2 + noise with u2 correlated to u1: the conditioned estimate matches the analytic
    response where coherence is high; the single-input ratio Gyu1 / Gu1u1 is biased by the correlation."""
    rng = np.random.default_rng(3)
    n = 20000
    u1 = rng.normal(size=n)
    u2 = 0.8 * u1 + 0.6 * rng.normal(size=n)
    g1 = ss.dlti([0.2, 0.1], [1.0, -1.2, 0.5], dt=DT)
    g2 = ss.dlti([0.3], [1.0, -0.7], dt=DT)
    _, y1 = ss.dlsim(g1, u1)
    _, y2 = ss.dlsim(g2, u2)
    y = y1[:, 0] + y2[:, 0] + 0.05 * rng.normal(size=n)
    u = np.stack([u1, u2], axis=1)
    est = estimate_frequency_response(u, y[:, None], DT, segment_seconds=2.0)
    f = np.asarray(est.freq)
    w = 2 * np.pi * f * DT
    _, ref1 = ss.dfreqresp(g1, w)
    _, ref2 = ss.dfreqresp(g2, w)
    H = np.asarray(est.response)[:, 0]
    good = np.asarray(est.coherence)[:, 0].min(axis=1) > 0.8
    assert good.sum() > 50
    np.testing.assert_allclose(H[good, 0], ref1[good], rtol=0.08, atol=0.02 * np.abs(ref1).max())
    np.testing.assert_allclose(H[good, 1], ref2[good], rtol=0.08, atol=0.02 * np.abs(ref2).max())
    assert np.all(np.asarray(est.multiple_coherence)[good, 0] > 0.9)
    single = estimate_frequency_response(u[:, :1], y[:, None], DT, segment_seconds=2.0)
    bias = np.abs(np.asarray(single.response)[good, 0, 0] - ref1[good]) / np.abs(ref1[good])
    assert np.median(bias) > 0.3


def _tf_response(A, B, C, j, s):
    num, den = ss.ss2tf(A, B, C, np.zeros((C.shape[0], B.shape[1])), input=j)
    return np.stack([np.polyval(row, s) for row in num], axis=-1) / np.polyval(den, s)[:, None]


def test_model_frequency_response_matches_ss2tf_for_table2():
    outputs = ("p", "q", "phi", "theta")
    freq = np.array([0.05, 0.3, 1.0, 2.5, 7.0])
    A, B = (np.asarray(m) for m in jaxheli.build_ab(jaxheli.TABLE2))
    C = np.asarray(output_matrix(outputs))
    H = np.asarray(model_frequency_response(jaxheli.TABLE2, freq, outputs))
    for j in range(4):
        np.testing.assert_allclose(H[:, :, j], _tf_response(A, B, C, j, 2j * np.pi * freq), rtol=1e-6, atol=1e-9)
    sysd = ss.cont2discrete((A, B, C, np.zeros((4, 4))), 0.01, method="zoh")
    Hd = np.asarray(model_frequency_response(jaxheli.TABLE2, freq, outputs, dt=0.01))
    z = np.exp(2j * np.pi * freq * 0.01)  # polynomials near z = 1 are ill-conditioned: numpy resolvent instead
    ref = np.stack([C @ np.linalg.solve(zk * np.eye(13) - sysd[0], sysd[1]) for zk in z])
    np.testing.assert_allclose(Hd, ref, rtol=1e-8, atol=1e-12)
    batch = np.stack([jaxheli.TABLE2, jaxheli.TABLE2 * 1.1])
    Hb = np.asarray(model_frequency_response(batch, freq, outputs))
    assert Hb.shape == (2, 5, 4, 4)
    np.testing.assert_allclose(Hb[0], H, rtol=1e-12)
    np.testing.assert_allclose(Hb[1], np.asarray(model_frequency_response(batch[1], freq, outputs)), rtol=1e-12)


def test_delayed_input_effect_peaks_at_its_lag_on_that_input():
    u = _sticks(5)
    delay = 0.23
    shift = int(round(delay / DT))
    effect = np.zeros(N)
    effect[shift:] = u[:-shift, 1]  # a pure gain path: a filter would add its group delay to the peak
    residual = np.stack([effect / effect.std() + 0.3 * _noise(6, N), 0.5 * _noise(7, N)], axis=1)
    measured = _noise(8, (N, 2))
    loc = localise(_flight(u, measured), measured - residual)
    pair = loc.lag.pairs["lon->p"]
    assert pair.significant
    assert abs(pair.peak_lag_s - delay) <= DT / 2
    others = [v for k, v in loc.lag.pairs.items() if k != "lon->p"]
    assert not any(v.significant for v in others)
    assert loc.summary.strongest_lag == pair
    content = json.loads(json.dumps(loc.to_json(), allow_nan=False))
    assert content["summary"]["strongest_lag"] == {"input": "lon", "channel": "p", "peak_lag_s": pair.peak_lag_s,
                                                   "peak_value": pair.peak_value, "threshold": pair.threshold,
                                                   "significant": True}
    assert Localisation.from_json(content) == loc and Localisation.from_json(content).to_json() == content


def test_residual_growing_with_amplitude_is_flagged_and_noise_is_not():
    windows = np.repeat(np.random.default_rng(9).uniform(0.2, 1.6, N // 250), 250)
    u = _sticks(10, envelope=windows)
    measured = _noise(11, (N, 2))
    cases = {
        "quadratic": np.stack([(u[:, 0] ** 2) * 50, 0.01 * _noise(12, N)], axis=1),
        "linear": np.stack([u[:, 0] * 5, 0.01 * _noise(12, N)], axis=1),
        "noise": np.stack([_noise(13, N), _noise(14, N)], axis=1),
    }
    result = {}
    for name, residual in cases.items():
        loc = localise(_flight(u, measured), measured - residual, window_seconds=2.5)
        result[name] = loc.window.amplitude_correlation
        assert loc.window.window_s == pytest.approx(2.5)
    assert result["quadratic"]["p"].significant and result["quadratic"]["p"].p_value < 1e-3
    assert result["quadratic"]["p"].exponent_ci[0] > 2.5
    lo, hi = result["linear"]["p"].exponent_ci
    assert lo < 2.0 < hi
    assert not result["noise"]["overall"].significant
    lo, hi = result["noise"]["overall"].exponent_ci
    assert lo < 0.0 < hi


def test_band_and_window_shares_sum_to_the_channel_gap():
    u = _sticks(15)
    t = DT * np.arange(N)
    measured = np.stack([np.sin(2 * np.pi * 0.3 * t) + 0.1 * _noise(16, N), _noise(17, N)], axis=1)
    residual = np.stack([0.4 * np.sin(2 * np.pi * 1.5 * t), 0.2 * _noise(18, N) + 0.05], axis=1)
    sim = measured - residual
    loc = localise(_flight(u, measured), sim)
    gap = np.sum(residual**2, axis=0) / np.sum((measured - measured.mean(axis=0)) ** 2, axis=0)
    np.testing.assert_allclose(gap, np.asarray(nmse(sim, measured)), rtol=1e-12)
    for c, name in enumerate(("p", "q")):
        assert loc.channel[name].nmse == pytest.approx(gap[c], rel=1e-12)
        parts = [b.channels[name] for b in loc.band]
        assert sum(p.share for p in parts) == pytest.approx(1.0, abs=1e-12)
        assert sum(p.nmse_part for p in parts) == pytest.approx(gap[c], rel=1e-10)
        assert sum(p.residual_power for p in parts) == pytest.approx(np.mean(residual[:, c] ** 2), rel=1e-10)
        assert sum(e[name] for e in loc.window.energy) == pytest.approx(gap[c], rel=1e-10)
    one_to_two = next(b for b in loc.band if b.range_hz == (1.0, 2.0))
    assert one_to_two.channels["p"].share > 0.999
    assert one_to_two.channels["p"].residual_power == pytest.approx(0.4**2 / 2, rel=1e-6)
    assert sum(loc.window.share) == pytest.approx(1.0, abs=1e-12)
    assert sum(c.share for c in loc.channel.values()) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="bands"):
        localise(_flight(u, measured), sim, bands=(0.0, 1.0, 2.0))


def test_white_residual_has_low_coherence_and_input_driven_residual_high():
    u = _sticks(19)
    driven = ss.sosfilt(ss.butter(2, 2.0, fs=1 / DT, output="sos"), u[:, 0] - 0.5 * u[:, 3])
    residual = np.stack([_noise(20, N), driven / driven.std() + 0.05 * _noise(21, N)], axis=1)
    measured = _noise(22, (N, 2))
    loc = localise(_flight(u, measured), measured - residual)
    for band in loc.band:
        white, structured = band.coherence["p"], band.coherence["q"]
        assert white.verdict == "noise"
        assert white.coherent_share < 0.35
        if band.range_hz[1] <= 2.0:
            assert structured.verdict == "structure" and structured.coherent_share > 0.9
            assert structured.by_input["lat"] > 0.8 and structured.by_input["lon"] < 0.3


def test_localise_command_on_flight_c(shared_data, tmp_path):
    """The command end to end on the paper's validation flight, checked against an independent simulation."""
    data = shared_data / "trex550" / "ppr_data.mat"
    names = ("p", "q", "phi", "theta")
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["localise", "--model", "table2", "--data", str(data), "--out", str(tmp_path),
                              "--outputs", ",".join(names), "--hold", "zoh", "--g", "9.8", "--x0", "zero"])
    assert args.func(args) == 0
    report = json.loads((tmp_path / "localisation.json").read_text())
    assert set(report) >= {"channel", "band", "window", "lag", "frequency_response", "summary", "simulation"}
    assert report["inputs"] == ["lat", "lon", "col"]  # the pedal column of flight C is zero
    flight = jaxheli.load(data)
    A, B = (np.asarray(m) for m in jaxheli.build_ab(jaxheli.TABLE2, g=9.8))
    sysd = ss.cont2discrete((A, B, np.asarray(output_matrix(names)), np.zeros((4, 4))), flight.dt,
                            method="zoh")
    _, ref, _ = ss.dlsim(sysd, flight.inputs)
    np.testing.assert_allclose([report["channel"][n]["nmse"] for n in names],
                               np.asarray(nmse(ref, flight.select(names).outputs)), rtol=1e-8)
    assert report["frequency_response"]["lat->p"]["bins"] > 0
    assert abs(report["frequency_response"]["lat->p"]["magnitude_db"]) < 6.0
    for name in ("residual_bands.png", "lag_correlation.png", "frequency_response.png"):
        assert (tmp_path / name).stat().st_size > 5000


def test_bad_input_is_named():
    u = _sticks(23)
    measured = _noise(24, (N, 2))
    with pytest.raises(ValueError, match="simulated"):
        localise(_flight(u, measured), measured[:, :1])
    perfect = localise(_flight(u, measured), measured)  # no residual: zero gap everywhere, no NaN
    assert perfect.channel["p"].nmse == 0.0 and sum(perfect.window.share) == 0.0
    with pytest.raises(ValueError, match="not finite"):
        localise(_flight(u, measured), np.full_like(measured, np.nan))
    with pytest.raises(ValueError, match="segment_seconds"):
        estimate_frequency_response(u, measured, DT, segment_seconds=100.0)
