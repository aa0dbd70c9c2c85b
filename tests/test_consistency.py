"""Data-consistency check: each defect injected into a synthetic piloted flight is found within its stated
1-sigma uncertainty, flagged, and undone by ``correct``; a clean flight flags nothing."""

import argparse
import json
import math

import numpy as np
import pytest

from jaxheli import load, piloted_flight, save_npz
from jaxheli.cli.gap import add_check_parser as add_parser
from jaxheli.gap._regress import hac_lstsq, well_posed
from jaxheli.data.flight import FlightDataError
from jaxheli.gap.consistency import Finding, check, correct

KEYS = {"kind", "channels", "estimate", "uncertainty", "significant", "message"}


@pytest.fixture(scope="module")
def clean():
    return piloted_flight(duration=30.0, seed=3)


def _col(flight, name):
    return flight.output_names.index(name)


def _with(flight, **columns):
    out = flight.outputs.copy()
    for name, values in columns.items():
        out[:, _col(flight, name)] = values
    return flight.replace(outputs=out)


def _rotate(flight, angle, signs=(1.0, 1.0)):
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]) @ np.diag(signs)
    uv = flight.outputs[:, [0, 1]] @ rot.T
    return _with(flight, u=uv[:, 0], v=uv[:, 1])


def _time_base(f):
    return f.replace(time=f.time[0] + 1.1 * (f.time - f.time[0]))


def _lag(f):
    return _with(f, p=np.interp(f.time - 0.06, f.time, f.output("p")))


def _rate_bias(f):
    return _with(f, q=f.output("q") + 0.02)


def _rate_drift(f):
    return _with(f, p=f.output("p") + 0.002 * (f.time - 0.5 * (f.time[0] + f.time[-1])))


def _u_lag(f):
    return _with(f, u=np.interp(f.time - 0.15, f.time, f.output("u")))


def _roll_offset(f):
    return _with(f, phi=f.output("phi") + 0.05)


def _pitch_drift(f):
    return _with(f, theta=f.output("theta") + 0.002 * (f.time - 0.5 * (f.time[0] + f.time[-1])))


DEFECTS = [
    # (inject, kind, channels, estimate key or None, true value)
    (_time_base, "time_scale", ("time",), None, 1.1),
    (_lag, "kinematic_lag", ("p", "phi"), None, 0.06),
    (_rate_bias, "rate_bias", ("q",), None, 0.02),
    (_rate_drift, "rate_drift", ("p",), None, 0.002),
    (lambda f: _rotate(f, math.radians(30.0)), "velocity_frame", ("u", "v"), "rotation", math.radians(30.0)),
    (lambda f: _rotate(f, 0.0, (-1.0, 1.0)), "velocity_frame", ("u", "v"), "scale_u", -1.0),
    (lambda f: _rotate(f, math.radians(-20.0), (1.0, -1.0)), "velocity_frame", ("u", "v"), "scale_v", -1.0),
    (_roll_offset, "attitude_bias", ("phi",), None, 0.05),
    (_pitch_drift, "attitude_drift", ("theta",), None, 0.002),
]


def _find(findings, kind, channels):
    hits = [f for f in findings if f.kind == kind and f.channels == channels]
    assert len(hits) == 1, f"expected one {kind} {channels} finding, got {hits}"
    return hits[0]


def test_clean_flight_flags_nothing(clean):
    findings = check(clean)
    assert not [f for f in findings if f.significant]
    kinds = {f.kind for f in findings}
    assert {"time_scale", "kinematic_lag", "rate_bias", "rate_drift", "velocity_frame", "attitude_bias",
            "velocity_lag", "velocity_bias", "velocity_drift"} <= kinds
    for f in findings:
        assert set(f.to_json()) == KEYS


@pytest.mark.parametrize("amplitude", [0.2, 0.4])
def test_a_clean_flight_sampled_at_20_hz_keeps_its_time_base(amplitude):
    """At the diagnosis's step (0.05 s), where the angle's central difference loses 3-10 % of its gain at the
    attitude's 1-3 Hz, the rate is compared in the difference's own form (Simpson's two-step mean): a perfectly
    clocked flight reads a time scale of 1 within 1 % and is not flagged (it read 1.03-1.10, flagged, before)."""
    from jaxheli import Excitation
    from jaxheli.gap.prepare import at_step

    excitation = Excitation("mixed", amplitude=(amplitude,) * 4, unit=0.3, band=(0.2, 4.0))
    flight = at_step(piloted_flight(duration=20.0, seed=5, excitation=excitation, noise=1.0), 0.05)
    (found,) = [f for f in check(flight) if f.kind == "time_scale"]
    assert abs(found.estimate - 1.0) < 0.01 and not found.significant, found.message


@pytest.mark.parametrize("inject, kind, channels, key, truth", DEFECTS,
                         ids=[f"{d[1]}-{d[3] or d[2][0]}" for d in DEFECTS])
def test_defect_found_within_uncertainty_and_corrected(clean, inject, kind, channels, key, truth):
    flight = inject(clean)
    findings = check(flight)
    found = _find(findings, kind, channels)
    est = found.estimate[key] if key else found.estimate
    sigma = found.uncertainty[key] if key else found.uncertainty
    assert found.significant, found.message
    assert 0 < sigma < 0.2 * abs(truth)
    assert abs(est - truth) < 3 * sigma, found.message
    others = [f for f in findings if f.significant and f is not found]
    assert not others, [f.message for f in others]

    fixed = correct(flight, findings)
    assert not [f.message for f in check(fixed) if f.significant]
    assert fixed.metadata["preprocessing"][-1]["applied"][0]["kind"] == kind
    assert "consistency.correct" == fixed.metadata["preprocessing"][-1]["step"]


def test_velocity_lag_found_within_uncertainty_and_not_corrected(clean):
    flight = _u_lag(clean)
    findings = check(flight)
    found = _find(findings, "velocity_lag", ("u", "theta"))
    assert found.significant and abs(found.estimate - 0.15) < 3 * found.uncertainty < 0.06, found.message
    assert [f.kind for f in findings if f.significant] == ["velocity_lag"]
    assert correct(flight, findings).output("u").tolist() == flight.output("u").tolist()


def test_correct_restores_the_clean_channels(clean):
    rotated = _rotate(clean, math.radians(30.0), (-1.0, 1.0))
    fixed = correct(rotated, check(rotated))
    uv = clean.outputs[:, [0, 1]]
    err = np.sqrt(np.mean((fixed.outputs[:, [0, 1]] - uv) ** 2)) / np.std(uv)
    assert err < 0.05
    stretched = _time_base(clean)
    findings = check(stretched)
    sigma = _find(findings, "time_scale", ("time",)).uncertainty
    restored = correct(stretched, findings)
    assert restored.time[0] == clean.time[0]
    assert abs(restored.duration - clean.duration) < 3 * sigma * clean.duration


def test_missing_constant_and_short_channels_never_crash(clean):
    angles_only = check(clean.select(("p", "q", "phi", "theta")))
    assert any(f.kind == "not_checked" and f.channels == ("u", "theta") for f in angles_only)
    assert not any(f.significant for f in angles_only)
    no_velocity = check(_with(clean, u=np.zeros(clean.n_samples), v=np.zeros(clean.n_samples)))
    assert [f.channels for f in no_velocity if f.kind == "not_checked"] == [
        ("r", "psi"), ("u", "theta"), ("v", "phi"), ("u", "theta"), ("v", "phi"), ("u",), ("v",)]
    one_axis = check(clean.select(("u", "theta", "q")))
    assert {f.kind for f in one_axis} >= {"time_scale", "velocity_scale", "attitude_bias", "not_checked"}
    short = check(clean.replace(time=clean.time[:150], inputs=clean.inputs[:150], outputs=clean.outputs[:150]))
    assert [f.kind for f in short] == ["not_checked"]
    assert correct(clean, short).outputs.tolist() == clean.outputs.tolist()


def test_single_velocity_channel_sign_flip(clean):
    flight = clean.select(("u", "theta", "q"))
    flipped = _with(flight, u=-flight.output("u"))
    found = _find(check(flipped), "velocity_scale", ("u",))
    assert found.significant and abs(found.estimate + 1.0) < 3 * found.uncertainty
    assert np.allclose(correct(flipped, [found]).output("u"), flight.output("u"))


def test_hac_standard_error_matches_ar1_long_run_variance():
    """Mean of an AR(1) series: the Newey-West error approaches sigma / (1 - rho) / sqrt(N)."""
    rng = np.random.default_rng(0)
    n, rho = 20000, 0.9
    e = rng.normal(size=n)
    x = np.empty(n)
    x[0] = e[0]
    for i in range(1, n):
        x[i] = rho * x[i - 1] + e[i]
    fit = hac_lstsq(x, np.ones((n, 1)), min_bandwidth=50)
    assert fit.beta[0] == pytest.approx(x.mean())
    assert fit.se[0] == pytest.approx(1.0 / (1.0 - rho) / np.sqrt(n), rel=0.2)
    assert not well_posed(np.stack([np.ones(n), 2 * np.ones(n)], axis=1))


def test_finding_json_is_plain():
    f = Finding("velocity_frame", ("u", "v"), {"rotation": np.float64(0.5)}, {"rotation": 0.01}, True, "m.")
    assert json.loads(json.dumps(f.to_json())) == {
        "kind": "velocity_frame", "channels": ["u", "v"], "estimate": {"rotation": 0.5},
        "uncertainty": {"rotation": 0.01}, "significant": True, "message": "m."}


def test_cli_handler_writes_json_and_plot(clean, tmp_path, capsys):
    path = tmp_path / "lagged.npz"
    save_npz(_lag(clean), path)
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["check", "--data", str(path), "--out", str(tmp_path / "out")])
    assert args.func(args) == 0
    rows = json.loads((tmp_path / "out" / "consistency.json").read_text())
    assert all(set(r) == KEYS for r in rows)
    lag = [r for r in rows if r["significant"]]
    assert [r["kind"] for r in lag] == ["kinematic_lag"] and abs(lag[0]["estimate"] - 0.06) < 0.01
    assert (tmp_path / "out" / "consistency.png").stat().st_size > 10000
    assert "kinematic_lag" in capsys.readouterr().out
    assert load(path).n_samples == clean.n_samples


SHARED = ["trex550/tested.mat", "trex550/Data_graphready.mat", "trex550/ppr_data.mat",
          "px4logs/2016-09-08/09_16_59.px4log", "px4logs/2016-08-09/13_25_39.px4log",
          "px4logs/sess006/log001.px4log", "px4logs/reference/log001.bin"]


@pytest.mark.parametrize("name", SHARED)
def test_every_shared_flight_reports_every_pair(shared_data, name):
    """Each kinematic pair has a lag with its sigma and each velocity a bias and drift, or a reason why not."""
    path = shared_data / name
    flight = load(path, missing_inputs="zero") if path.suffix == ".bin" else load(path)
    findings = check(flight)
    assert all(set(f.to_json()) == KEYS for f in findings)
    json.dumps([f.to_json() for f in findings], allow_nan=False)
    correct(flight, findings)
    if flight.duration < 3.0:
        assert [f.kind for f in findings] == ["not_checked"]
        return
    for kind, channels in [("kinematic_lag", ("p", "phi")), ("kinematic_lag", ("q", "theta")),
                           ("velocity_lag", ("u", "theta")), ("velocity_lag", ("v", "phi")),
                           ("velocity_lag", ("w", "phi", "theta"))]:
        hits = [f for f in findings if f.channels == channels and f.kind == kind]
        if hits:
            (hit,) = hits
            assert np.isfinite(hit.estimate) and 0 < hit.uncertainty < 1.0, hit.message
            assert "ms (1 sigma" in hit.message
        else:
            assert any(f.channels == channels and f.kind == "not_checked" for f in findings)
            assert channels[0] not in flight.output_names or np.ptp(flight.output(channels[0])) == 0
    assert [f.kind for f in findings if f.channels == ("r", "psi")] == ["not_checked"]
    biased = [f.channels for f in findings if f.kind == "velocity_bias" and f.significant]
    assert biased == ([("w",)] if name == "trex550/Data_graphready.mat" else []), name
    for vel in ("u", "v", "w"):
        kinds = sorted(f.kind for f in findings if f.channels == (vel,) and "velocity" in f.kind or
                       f.channels == (vel,) and f.kind == "not_checked")
        assert kinds in (["velocity_bias", "velocity_drift"], ["not_checked"]), (vel, kinds)


def test_parameter_file_is_not_a_flight(shared_data):
    with pytest.raises(FlightDataError, match="inr"):
        load(shared_data / "trex550" / "Record.mat")


def test_correct_names_a_missing_channel(clean):
    finding = Finding("rate_bias", ("p",), 0.1, 0.001, True, "p has a bias.")
    with pytest.raises(ValueError, match="channel 'p'"):
        correct(clean.select(("q", "theta")), [finding])
    no_rates = check(clean.select(("u", "v", "phi", "theta")))
    assert [f.channels for f in no_rates if f.kind == "not_checked"][:3] == [("time",), ("p", "phi"), ("q", "theta")]
    json.dumps([f.to_json() for f in no_rates], allow_nan=False)
