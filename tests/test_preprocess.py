"""Preprocessing against independent numpy/scipy computations; purity and the preprocessing log."""

import numpy as np
import pytest

from jaxheli.data.flight import FlightData, FlightDataError
from jaxheli.io import load
from jaxheli.data.preprocess import detrend, from_samples, lowpass, resample, split, trim


def _flight(n=2001, dt=0.01, t0=0.0, outputs=None, names=("p", "q")):
    t = t0 + dt * np.arange(n)
    if outputs is None:
        outputs = np.column_stack([2.0 * t + 1.0, -t + 0.5])
    inputs = np.column_stack([0.1 * t, 0.2 * t, 0.0 * t, 0.3 * t + 0.4])
    return FlightData(t, inputs, outputs, names, "synthetic", {"reader": "test"})


def test_lowpass_removes_20hz_keeps_half_hz():
    t = 0.01 * np.arange(2001)
    slow, fast = np.sin(2 * np.pi * 0.5 * t), np.sin(2 * np.pi * 20 * t)
    flight = _flight(outputs=np.column_stack([slow + fast, fast]))
    out = lowpass(flight, cutoff_hz=2.0)
    inner = slice(200, -200)  # away from the edge transients
    np.testing.assert_allclose(out.output("p")[inner], slow[inner], atol=2e-3)
    assert np.abs(out.output("q")[inner]).max() < 1e-3
    assert out.metadata["preprocessing"] == [
        {"step": "lowpass", "cutoff_hz": 2.0, "order": 4, "zero_phase": True, "include_inputs": True}]
    np.testing.assert_allclose(out.inputs[inner], flight.inputs[inner], atol=1e-6)  # ramps pass


def test_lowpass_gain_at_cutoff_is_one_half():
    """Forward-backward filtering squares the Butterworth gain: |H(fc)|^2 = 1/2, in Hz."""
    t = 0.005 * np.arange(8001)
    flight = _flight(n=8001, dt=0.005, outputs=np.sin(2 * np.pi * 3.0 * t)[:, None], names=("r",))
    out = lowpass(flight, cutoff_hz=3.0, order=2, include_inputs=False)
    amp = np.abs(out.outputs[2000:-2000, 0]).max()
    assert amp == pytest.approx(0.5, abs=0.01)
    np.testing.assert_array_equal(out.inputs, flight.inputs)


def test_lowpass_errors():
    with pytest.raises(FlightDataError, match=r"synthetic: field 'cutoff_hz': 50.0 Hz.*Nyquist"):
        lowpass(_flight(), 50.0)
    with pytest.raises(FlightDataError, match="too few for an order-4"):
        lowpass(_flight(n=12), 5.0)


def test_resample_linear_ramp_exact():
    flight = _flight(t0=3.0)
    out = resample(flight, 0.025)
    assert out.n_samples == 801 and out.dt == pytest.approx(0.025)
    np.testing.assert_allclose(out.output("p"), 2.0 * out.time + 1.0, rtol=1e-12)
    np.testing.assert_allclose(out.inputs[:, 3], 0.3 * out.time + 0.4, rtol=1e-12)
    assert out.metadata["preprocessing"] == [{"step": "resample", "dt": 0.025, "from_dt": pytest.approx(0.01)}]
    assert resample(flight, 0.003).n_samples == 6667  # upsampling: floor(20 / 0.003) + 1


def test_from_samples_uneven_ramp_exact():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.005, 0.015, size=300))
    inputs = np.column_stack([t, -t, 0 * t, 2 * t])
    flight = from_samples(t, inputs, (3 * t - 1)[:, None], ["w"], "raw.log", dt=0.01, metadata={"k": 1})
    assert flight.time[0] == t[0] and flight.dt == pytest.approx(0.01)
    np.testing.assert_allclose(flight.output("w"), 3 * flight.time - 1, rtol=1e-12)
    np.testing.assert_allclose(flight.inputs[:, 3], 2 * flight.time, rtol=1e-12)
    assert flight.metadata == {"k": 1, "preprocessing": [{"step": "from_samples", "dt": 0.01, "raw_samples": 300}]}
    assert from_samples(t, inputs, t[:, None], ["w"]).dt == pytest.approx(np.median(np.diff(t)))


def test_from_samples_errors():
    t = np.array([0.0, 0.1, 0.1, 0.3])
    with pytest.raises(FlightDataError, match=r"raw\.log: field 'time': not strictly increasing at sample 2"):
        from_samples(t, np.zeros((4, 4)), np.zeros((4, 1)), ["p"], "raw.log")
    with pytest.raises(FlightDataError, match=r"raw\.log: field 'outputs': expected 3 rows"):
        from_samples(t[:3] * [1, 1, 2], np.zeros((3, 4)), np.zeros((4, 1)), ["p"], "raw.log")
    with pytest.raises(FlightDataError, match="field 'dt': sample time must be a positive"):
        from_samples(np.arange(3.0), np.zeros((3, 4)), np.zeros((3, 1)), ["p"], "raw.log", dt=-1)


def test_trim_by_time_and_samples():
    flight = _flight()
    out = trim(flight, start=2.0, stop=15.0)
    assert (out.time[0], out.time[-1]) == pytest.approx((2.0, 15.0))
    assert out.n_samples == 1301
    both = trim(flight, drop_samples=50)
    np.testing.assert_array_equal(both.time, flight.time[50:-50])
    head_only = trim(flight, drop_samples=(10, 0))
    np.testing.assert_array_equal(head_only.outputs, flight.outputs[10:])
    assert both.metadata["preprocessing"][0]["drop_samples"] == [50, 50]
    with pytest.raises(FlightDataError, match=r"synthetic: field 'time': trim\(start=30.*leaves 0 samples"):
        trim(flight, start=30.0)
    with pytest.raises(FlightDataError, match="'drop_samples': must be >= 0"):
        trim(flight, drop_samples=-1)


def test_detrend_against_numpy():
    flight = _flight()
    const = detrend(flight)
    np.testing.assert_allclose(const.outputs.mean(axis=0), 0.0, atol=1e-12)
    offsets = const.metadata["preprocessing"][0]["offsets"]
    assert offsets == pytest.approx({"p": flight.output("p").mean(), "q": flight.output("q").mean()})
    np.testing.assert_array_equal(const.inputs, flight.inputs)
    noise = np.random.default_rng(2).normal(size=flight.n_samples)
    wavy = flight.replace(outputs=flight.outputs + noise[:, None])
    lin = detrend(wavy, kind="linear", channels=["q", "col"])
    slope, icpt = np.polyfit(flight.time, noise - 0.5 - flight.time, 1)
    np.testing.assert_allclose(lin.output("q"), noise - 0.5 - flight.time - (slope * flight.time + icpt), atol=1e-9)
    np.testing.assert_allclose(lin.inputs[:, 3], 0.0, atol=1e-12)
    np.testing.assert_array_equal(lin.output("p"), wavy.output("p"))
    with pytest.raises(FlightDataError, match=r"field 'channels': \['w'\] not in the flight"):
        detrend(flight, channels=["w"])
    with pytest.raises(FlightDataError, match="field 'kind'"):
        detrend(flight, kind="quadratic")


def test_split_lengths_and_continuity():
    flight = _flight(n=1000)
    train, valid = split(flight)
    assert (train.n_samples, valid.n_samples) == (700, 300)
    assert valid.time[0] == pytest.approx(train.time[-1] + flight.dt)
    np.testing.assert_array_equal(np.concatenate([train.outputs, valid.outputs]), flight.outputs)
    assert [m["part"] for m in (train.metadata["preprocessing"][0], valid.metadata["preprocessing"][0])] == [
        "train", "validation"]
    assert split(flight, 0.25)[0].n_samples == 250
    for bad in (0.0, 1.0, 0.001):
        with pytest.raises(FlightDataError, match="field 'fraction'"):
            split(flight, bad)


def test_steps_are_pure_and_logged_in_order(shared_data):
    flight = load(shared_data / "trex550" / "Data_graphready.mat")
    before = flight.outputs.copy()
    train, _ = split(detrend(lowpass(trim(flight, drop_samples=50), 5.0), channels=["phi"]), 0.5)
    np.testing.assert_array_equal(flight.outputs, before)
    assert "preprocessing" not in flight.metadata
    assert [s["step"] for s in train.metadata["preprocessing"]] == ["trim", "lowpass", "detrend", "split"]
    assert train.metadata["reader"] == "mat" and train.n_samples == 4245
    assert abs(train.output("phi").mean()) < 0.1
