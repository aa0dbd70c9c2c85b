"""Excitation signals and piloted synthetic flights, against analytic properties and scipy references."""

import numpy as np
import pytest
import scipy.signal

from jaxheli.synth.excitation import Excitation, doublet, multisine, sweep, three_two_one_one
from jaxheli.model import INPUT_NAMES, R50_G, R50_HOVER, STATE_NAMES, TABLE2, build_ab
from jaxheli.synth.piloted import DEFAULT_NOISE, DEFAULT_OUTPUTS, Pilot, default_flight, piloted_flight

DT = 0.01
T = np.arange(0.0, 20.0, DT)
SHORT = Excitation("3211", unit=0.3)  # fits records from 10 s


def _runs(x: np.ndarray) -> list[tuple[float, int]]:
    """Run-length encoding ``[(value, length)]`` of a piecewise-constant signal."""
    change = np.flatnonzero(np.diff(x)) + 1
    bounds = np.concatenate([[0], change, [x.size]])
    return [(float(x[a]), int(b - a)) for a, b in zip(bounds[:-1], bounds[1:])]


def _truth_states(theta, g, inputs, n):
    """Independent open-loop truth response: scipy ZOH discretisation and ``dlsim`` from trim."""
    A, B = (np.asarray(M) for M in build_ab(theta, g))
    sysd = scipy.signal.cont2discrete((A, B, np.eye(13), np.zeros((13, 4))), DT, method="zoh")
    _, _, x = scipy.signal.dlsim(sysd, inputs[:n], x0=np.zeros(13))
    return x


# ---- signals -------------------------------------------------------------------------------------------


def test_doublet_widths_signs_and_zero_integral():
    x = doublet(T, start=2.0, width=0.7, amplitude=0.3)
    assert _runs(x) == [(0.0, 200), (0.3, 70), (-0.3, 70), (0.0, T.size - 340)]
    assert abs(x.sum() * DT) < 1e-12


def test_three_two_one_one_pulses():
    x = three_two_one_one(T, start=1.0, unit=0.4, amplitude=-0.15)
    assert _runs(x) == [(0.0, 100), (-0.15, 120), (0.15, 80), (-0.15, 40), (0.15, 40), (0.0, T.size - 380)]
    span = x[100:380]
    # The classical 3-2-1-1 (+3 -2 +1 -1 units) has a net area of one unit, i.e. mean A/7 over its span.
    assert span.sum() * DT == pytest.approx(-0.15 * 0.4, abs=1e-12)
    assert span.mean() == pytest.approx(-0.15 / 7, abs=1e-12)


def test_sweep_instantaneous_frequency_from_zero_crossings():
    t = np.arange(0.0, 30.0, 0.001)
    f0, f1, start, duration = 0.3, 4.0, 2.0, 25.0
    x = sweep(t, f0, f1, start, duration, 0.2, fade=2.0)
    assert np.all(x[(t < start) | (t > start + duration)] == 0.0)
    assert np.max(np.abs(x)) <= 0.2 and np.max(np.abs(x)) > 0.19
    inside = (t > start) & (t < start + duration)
    ti, xi = t[inside], x[inside]
    k = np.flatnonzero(xi[:-1] * xi[1:] < 0)
    crossings = ti[k] - xi[k] * (ti[k + 1] - ti[k]) / (xi[k + 1] - xi[k])
    f_est = 0.5 / np.diff(crossings)
    mid = 0.5 * (crossings[1:] + crossings[:-1]) - start
    f_true = f0 * (f1 / f0) ** (mid / duration)
    np.testing.assert_allclose(f_est, f_true, rtol=0.02)
    assert f_est[0] < 1.3 * f0 and f_est[-1] > 0.97 * f1


def test_multisine_peak_crest_factor_and_spectrum():
    t = np.arange(0.0, 20.0, DT)  # 20 s: every frequency below has whole periods
    freqs = np.arange(1, 21) * 0.25
    x = multisine(t, freqs, 0.1)
    assert np.max(np.abs(x)) == pytest.approx(0.1, rel=1e-12)
    crest = np.max(np.abs(x)) / np.sqrt(np.mean(x**2))
    in_phase = np.sqrt(2 * freqs.size)  # crest factor of zero phases
    assert crest < 2.0 < in_phase
    spectrum = np.abs(np.fft.rfft(x))
    bins = np.rint(freqs * t.size * DT).astype(int)
    np.testing.assert_allclose(spectrum[bins], spectrum[bins][0], rtol=1e-9)
    others = np.delete(spectrum, bins)
    assert np.max(others) < 1e-9 * spectrum[bins][0]
    random = multisine(t, freqs, 0.1, phases="random", seed=4)
    np.testing.assert_array_equal(random, multisine(t, freqs, 0.1, phases="random", seed=4))
    assert not np.allclose(random, multisine(t, freqs, 0.1, phases="random", seed=5))


@pytest.mark.parametrize(
    "call",
    [
        lambda: doublet(T, 1.0, 0.0, 0.1),
        lambda: doublet(np.zeros((3, 2)), 1.0, 0.5, 0.1),
        lambda: three_two_one_one(T, 1.0, -0.5, 0.1),
        lambda: three_two_one_one(T, np.nan, 0.5, 0.1),
        lambda: sweep(T, 0.0, 2.0, 0.0, 10.0, 0.1),
        lambda: sweep(T, 0.5, 60.0, 0.0, 10.0, 0.1),  # above Nyquist (50 Hz)
        lambda: sweep(T, 0.5, 2.0, 0.0, 10.0, 0.1, fade=6.0),
        lambda: multisine(T, [], 0.1),
        lambda: multisine(T, [1.0, 1.0], 0.1),
        lambda: multisine(T, [1.0, -2.0], 0.1),
        lambda: multisine(T, [1.0], 0.1, phases="zero"),
        lambda: Excitation("chirp"),
        lambda: Excitation(amplitude=(0.1, 0.1, 0.1)),
        lambda: Excitation(amplitude=(0.1, 0.1, 0.1, 1.5)),
        lambda: Excitation("3211", unit=2.0)(T),  # 14 s manoeuvre in a 4.75 s slot
    ],
)
def test_signal_argument_errors(call):
    with pytest.raises(ValueError):
        call()


def test_excitation_schedule_axes_in_turn():
    t = np.arange(0.0, 41.0, DT)
    sticks = Excitation("3211", amplitude=(0.1, 0.2, 0.3, 0.4), unit=0.5, lead=1.0)(t)
    first = [np.flatnonzero(sticks[:, i])[0] * DT for i in range(4)]
    np.testing.assert_allclose(first, [1.0, 11.0, 21.0, 31.0], atol=DT / 2)
    np.testing.assert_allclose(np.abs(sticks).max(axis=0), [0.1, 0.2, 0.3, 0.4])
    assert np.count_nonzero(sticks, axis=1).max() == 1  # one axis at a time


# ---- piloted flights -----------------------------------------------------------------------------------


@pytest.mark.parametrize(("theta", "g", "gust"), [(TABLE2, 9.81, 1.0), (R50_HOVER, R50_G, 3.0)],
                         ids=["table2", "r50"])
def test_pilot_stabilises_open_loop_unstable_truth(theta, g, gust):
    A, _ = build_ab(theta, g)
    assert np.max(np.linalg.eigvals(np.asarray(A)).real) > 0.04  # open-loop unstable truth
    flight = piloted_flight(theta, g=g, duration=120.0, gust=gust, seed=3)
    out = {name: np.max(np.abs(flight.output(name))) for name in flight.output_names}
    assert max(out["phi"], out["theta"]) < 0.5
    assert max(out["p"], out["q"]) < 3.0
    assert max(out["u"], out["v"], out["w"]) < 10.0
    assert np.all(np.abs(flight.inputs) <= 1.0)
    assert max(flight.metadata["pilot"]["closed_loop_pole_magnitudes"]) < 1.0
    # The same sticks flown open loop (no pilot, no gusts) leave the envelope: the pilot matters.
    x = _truth_states(theta, g, flight.inputs, flight.n_samples)
    i = {s: STATE_NAMES.index(s) for s in STATE_NAMES}
    escaped = (np.abs(x[:, [i["phi"], i["theta"]]]).max() > 0.5 or np.abs(x[:, [i["p"], i["q"]]]).max() > 3.0
               or np.abs(x[:, [i["u"], i["v"], i["w"]]]).max() > 10.0)
    assert escaped


def test_outputs_are_truth_response_to_recorded_sticks():
    flight = piloted_flight(TABLE2, duration=20.0, excitation=SHORT, noise=0.0, gust=0.0, seed=1)
    n = int(10.0 / DT)
    x = _truth_states(TABLE2, 9.81, flight.inputs, n)
    cols = [STATE_NAMES.index(c) for c in flight.output_names]
    np.testing.assert_allclose(flight.outputs[:n], x[:, cols], rtol=0, atol=1e-9)
    assert np.max(np.abs(x[:, cols])) > 0.05  # the window holds a real response


def test_measurement_noise_levels_and_independence_from_the_loop():
    clean = piloted_flight(TABLE2, duration=60.0, noise=0.0, seed=2)
    noisy = piloted_flight(TABLE2, duration=60.0, noise=2.0, seed=2)
    np.testing.assert_array_equal(noisy.inputs, clean.inputs)  # the pilot feeds back the true state
    residual_std = np.std(noisy.outputs - clean.outputs, axis=0)
    np.testing.assert_allclose(residual_std, [2.0 * DEFAULT_NOISE[c] for c in DEFAULT_OUTPUTS], rtol=0.05)
    assert noisy.metadata["noise"] == {c: 2.0 * DEFAULT_NOISE[c] for c in DEFAULT_OUTPUTS}


def test_reproducible_from_seed_and_different_across_seeds():
    a, b, c = (piloted_flight(TABLE2, duration=20.0, excitation=SHORT, gust=0.5, seed=s) for s in (7, 7, 8))
    np.testing.assert_array_equal(a.inputs, b.inputs)
    np.testing.assert_array_equal(a.outputs, b.outputs)
    assert not np.allclose(a.outputs, c.outputs)
    assert not np.allclose(a.inputs, c.inputs)  # different gusts, different pilot response


def test_sticks_saturate_at_unit_magnitude():
    sticks = np.zeros((2001, 4))
    sticks[100:300, 1] = 1.5
    flight = piloted_flight(TABLE2, duration=20.0, excitation=sticks, noise=0.0)
    assert np.max(np.abs(flight.inputs)) == 1.0
    assert flight.metadata["saturated_fraction"] > 0.0
    assert flight.metadata["excitation"] == {"kind": "array"}


def test_pilot_with_reaction_delay_stays_in_control():
    flight = piloted_flight(R50_HOVER, g=R50_G, duration=60.0, gust=2.0, pilot=Pilot(delay=0.15))
    assert flight.metadata["pilot"]["delay_s"] == pytest.approx(0.15)
    assert max(flight.metadata["pilot"]["closed_loop_pole_magnitudes"]) < 1.0
    assert np.max(np.abs(flight.output("phi"))) < 0.5


def test_metadata_and_output_selection():
    noise = {"p": 0.0, "q": 0.1, "a": 0.0}
    flight = piloted_flight(TABLE2, duration=10.0, excitation=SHORT, outputs=("p", "q", "a"), noise=noise)
    assert flight.output_names == ("p", "q", "a")
    meta = flight.metadata
    assert meta["generator"] == "jaxheli.synth.piloted_flight"
    np.testing.assert_array_equal(meta["truth"], TABLE2)
    assert meta["g"] == 9.81 and meta["seed"] == 0 and meta["gust"]["std"] == 0.0
    assert meta["noise"] == {"p": 0.0, "q": 0.1, "a": 0.0}
    assert np.asarray(meta["pilot"]["gain"]).shape == (4, 13)
    assert meta["pilot"]["open_loop_max_real_pole"] == pytest.approx(0.045724, abs=1e-6)


def test_unstabilisable_model_is_rejected():
    theta = TABLE2.copy()
    theta[31:] = 0.0  # no control derivatives: the unstable heave mode cannot be reached
    with pytest.raises(ValueError, match="Pilot"):
        piloted_flight(theta, duration=5.0, excitation=np.zeros((501, 4)))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"theta": np.zeros(39)},
        {"dt": 0.0},
        {"duration": 0.001},
        {"duration": 5.0},  # the excitation does not fit
        {"gust": -1.0},
        {"seed": 1.5},
        {"outputs": ("p", "r_fb")},
        {"noise": {"p": 0.1}},
        {"noise": -1.0},
        {"excitation": np.zeros((10, 4))},
    ],
)
def test_piloted_flight_argument_errors(kwargs):
    with pytest.raises(ValueError):
        piloted_flight(**{"duration": 10.0, "excitation": SHORT, **kwargs})


@pytest.mark.parametrize("kwargs", [{"max_state": {"x": 1.0}}, {"max_state": {"phi": 0.0}}, {"max_stick": -0.1},
                                    {"delay": -0.01}])
def test_pilot_argument_errors(kwargs):
    with pytest.raises(ValueError, match="Pilot"):
        Pilot(**kwargs)


def test_default_flight():
    flight = default_flight()
    assert default_flight() is flight
    assert flight.n_samples == 8001 and flight.dt == pytest.approx(0.01)
    assert flight.output_names == DEFAULT_OUTPUTS
    np.testing.assert_array_equal(flight.metadata["truth"], TABLE2)
    assert all(flight.metadata["stick_rms"][axis] > 0.01 for axis in INPUT_NAMES)
    assert flight.metadata["saturated_fraction"] == 0.0
    with pytest.raises(ValueError):
        flight.outputs[0, 0] = 1.0  # read-only: the cached flight cannot be corrupted
    again = piloted_flight(TABLE2, duration=80.0, excitation=Excitation(), seed=0)
    np.testing.assert_array_equal(again.outputs, flight.outputs)
