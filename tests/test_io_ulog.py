"""PX4 ULog: logs written by the test (``ulog_writer``) from known flights, read back through ``jaxheli.load``;
references are the known signals, scipy rotations and hand-computed RC calibrations."""

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from ulog_writer import RC_PARAMS, message, stick_to_pwm, ulog_bytes, write_flight_ulog

from jaxheli import piloted_flight
from jaxheli.synth.excitation import Excitation
from jaxheli.data.flight import FlightDataError
from jaxheli.io import DEFAULT_ULOG, load, load_ulog

ALL_OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")


@pytest.fixture(scope="module")
def truth():
    return piloted_flight(duration=4.0, dt=0.01, seed=4, excitation=Excitation(kind="3211", unit=0.1, lead=0.2))


@pytest.fixture(scope="module")
def truth_log(truth, tmp_path_factory):
    return write_flight_ulog(truth, tmp_path_factory.mktemp("ulog") / "flight.ulg")


def _stamps(t):
    return (1_000_000 + np.round(np.asarray(t) * 1e6)).astype(np.uint64)


def _attitude_only(n=20, path=None):
    """A one-topic log: vehicle_attitude at 100 Hz, roll 0.01 k rad; each data message is 29 bytes."""
    quat = Rotation.from_euler("x", 0.01 * np.arange(n)[:, None]).as_quat()[:, [3, 0, 1, 2]]
    data = ulog_bytes({"vehicle_attitude": {"timestamp": _stamps(0.01 * np.arange(n)), "q": quat}})
    if path is not None:
        path.write_bytes(data)
    return data


ROLL = {"phi": ("vehicle_attitude", "roll(q)")}

# --- round trip of a piloted flight --------------------------------------------------------------------------


def test_flight_round_trip(truth, truth_log):
    """Angles from quaternions, body velocities from rotated NED velocities, rates and RC sticks equal the
    flight that was written (float32 storage, RC pulses rounded to 1 us)."""
    flight = load(truth_log)
    assert flight.output_names == ALL_OUTPUTS and flight.n_samples == truth.n_samples
    np.testing.assert_allclose(flight.time, truth.time + 0.05, atol=1e-9)  # header start 50 ms before the data
    for name in ALL_OUTPUTS:
        np.testing.assert_allclose(flight.output(name), truth.output(name), atol=3e-6, err_msg=name)
    np.testing.assert_allclose(flight.inputs, truth.inputs, atol=0.5 / 370)  # half a pulse step, finest channel
    assert np.ptp(truth.output("u")) > 0.01 and np.ptp(truth.inputs[:, 1]) > 0.05  # the signals move
    meta = flight.metadata
    assert meta["reader"] == "ulog" and meta["dropped"] == {} and meta["problems"] == []
    assert meta["channels"]["u"] == "vehicle_local_position.body_x(vx,vy,vz)"
    assert meta["channels"]["col"] == "input_rc.rc(values[5])"
    assert meta["messages"]["vehicle_attitude"] == truth.n_samples


def test_dispatch_by_magic_bytes(truth_log, tmp_path):
    renamed = tmp_path / "flight.dat"
    renamed.write_bytes(truth_log.read_bytes())
    assert load(renamed).metadata["reader"] == "ulog"


def test_rc_calibration_hand_computed(tmp_path):
    """PX4 rc_update on pulses of known value: clipping, dead zone, both slopes, reversal, PX4 defaults."""
    pulses = np.array([[1000, 990, 1500, 1500], [1250, 1515, 1490, 1000], [1500, 1760, 1440, 1250],
                       [1750, 1260, 1700, 1990], [2100, 2010, 1100, 900]])
    values = np.full((5, 18), 1500, dtype=np.uint16)
    values[:, [0, 1, 3, 5]] = pulses
    params = {k: v for k, v in RC_PARAMS.items() if not k.startswith("RC6")}  # channel 6: PX4 defaults (dz 10)
    topics = {"input_rc": {"timestamp": _stamps(0.02 * np.arange(5)), "values": values},
              "vehicle_angular_velocity": {"timestamp": _stamps(0.02 * np.arange(5)), "xyz": np.zeros((5, 3))}}
    path = tmp_path / "rc.ulg"
    path.write_bytes(ulog_bytes(topics, params))
    flight = load(path, strict=False)  # 5 samples: too short to identify from, read anyway
    expected = np.array([
        [-1.0, 1.0, 10 / 410, 0.0],
        [-0.5, 0.0, 0.0, -1.0],
        [0.0, -245 / 495, -30 / 370, -240 / 490],
        [0.5, 245 / 515, 210 / 410, 480 / 490],
        [1.0, -1.0, -1.0, -1.0],
    ])
    np.testing.assert_allclose(flight.inputs, expected, atol=1e-12)
    assert flight.output_names == ("p", "q", "r")
    assert set(flight.metadata["dropped"]) == {"u", "v", "w", "phi", "theta"}


def test_stick_to_pwm_inverts_the_calibration(tmp_path):
    """The test's pulse writer and the reader's calibration are inverses to half a pulse step."""
    sticks = np.linspace(-1, 1, 41)
    values = np.full((41, 18), 1500, dtype=np.uint16)
    for channel in (1, 2, 4):
        values[:, channel - 1] = stick_to_pwm(sticks, channel)
    stamps = _stamps(0.01 * np.arange(41))
    path = tmp_path / "sticks.ulg"
    path.write_bytes(ulog_bytes({"input_rc": {"timestamp": stamps, "values": values},
                                 "vehicle_attitude": {"timestamp": stamps, "q": np.tile([1.0, 0, 0, 0], (41, 1))}},
                                RC_PARAMS))
    flight = load(path)
    np.testing.assert_array_equal(flight.inputs[:, 3], 0.0)  # channel 6 held at its trim
    for col, tol in enumerate((0.5 / 500, 0.5 / 495, 0.5 / 370)):
        np.testing.assert_allclose(flight.inputs[:, col], sticks, atol=tol)


# --- fallbacks, rates, the quaternion sign --------------------------------------------------------------------


@pytest.mark.parametrize("modern", [True, False])
def test_fallback_topics_and_different_rates(tmp_path, modern):
    """No vehicle_angular_velocity / input_rc: sensor_combined and manual_control_setpoint take over. Attitude
    at 200 Hz with every other quaternion negated, velocity at 50 Hz between attitude stamps, sticks at 50 Hz."""
    ta, tv = 0.005 * np.arange(401), 0.0025 + 0.02 * np.arange(99)
    yaw = 3.0 + 0.8 * ta  # crosses +-pi
    quat = Rotation.from_euler("ZYX", np.column_stack([yaw, -0.05 + 0 * ta, 0.1 + 0 * ta])).as_quat()[:, [3, 0, 1, 2]]
    quat[1::2] *= -1
    ned = np.array([2.0, -1.0, 0.5])
    sticks = {"roll": 0.2 * tv, "pitch": -0.1 * tv, "yaw": 0.05 - 0 * tv, "throttle": tv / 4 - 0.5}
    if not modern:
        sticks = {"y": sticks["roll"], "x": sticks["pitch"], "r": sticks["yaw"], "z": (sticks["throttle"] + 1) / 2}
    topics = {
        "vehicle_attitude": {"timestamp": _stamps(ta), "q": quat},
        "sensor_combined": {"timestamp": _stamps(ta), "gyro_rad": np.column_stack([ta, -ta, 2 * ta])},
        "vehicle_local_position": {"timestamp": _stamps(tv), **{k: np.full(tv.size, v) for k, v in zip(
            ("vx", "vy", "vz"), ned)}},
        "manual_control_setpoint": {"timestamp": _stamps(tv), **sticks},
    }
    path = tmp_path / "fallback.ulg"
    path.write_bytes(ulog_bytes(topics, start_us=1_000_000))
    flight = load(path)
    t = flight.time
    assert flight.dt == pytest.approx(0.005) and t[0] == pytest.approx(tv[0]) and t[-1] <= tv[-1] + 1e-9
    np.testing.assert_allclose(flight.output("p"), t, atol=1e-6)
    np.testing.assert_allclose(flight.output("r"), 2 * t, atol=1e-6)
    np.testing.assert_allclose(flight.output("phi"), 0.1, atol=1e-6)
    np.testing.assert_allclose(flight.output("theta"), -0.05, atol=1e-6)
    rot = Rotation.from_euler("ZYX", np.column_stack([3.0 + 0.8 * t, -0.05 + 0 * t, 0.1 + 0 * t]))
    body = rot.inv().apply(ned)  # exact body velocity; the log's is sampled at 50 Hz, then interpolated
    for k, name in enumerate("uvw"):
        np.testing.assert_allclose(flight.output(name), body[:, k], atol=2e-4, err_msg=name)
    np.testing.assert_allclose(flight.inputs, np.column_stack([0.2 * t, 0.1 * t, 0.05 + 0 * t, t / 4 - 0.5]),
                               atol=1e-6)
    channels = flight.metadata["channels"]
    assert channels["p"] == "sensor_combined.gyro_rad[0]"
    assert channels["lon"] == ("manual_control_setpoint.pitch x -1" if modern else "manual_control_setpoint.x x -1")
    assert modern or channels["col"] == "manual_control_setpoint.z x 2 - 1"


def test_instances_and_explicit_scale(tmp_path):
    ta = 0.01 * np.arange(10)
    topics = {"sensor_gyro": {"timestamp": _stamps(ta), "x": ta}, "sensor_gyro:1": {"timestamp": _stamps(ta), "x": -ta}}
    path = tmp_path / "multi.ulg"
    path.write_bytes(ulog_bytes(topics))
    flight = load(path, channels={"p": ("sensor_gyro", "x"), "q": ("sensor_gyro:1", "x", 2.0, 1.0)},
                  missing_inputs="zero", rate_hz=50, strict=False)  # 5 samples: read anyway
    assert flight.dt == pytest.approx(0.02) and flight.n_samples == 5
    np.testing.assert_allclose(flight.output("p"), flight.time - flight.time[0] + ta[0], atol=1e-7)
    np.testing.assert_allclose(flight.output("q"), 1 - 2 * flight.output("p"), atol=1e-7)
    assert flight.metadata["zero_inputs"] == ["lat", "lon", "ped", "col"]


# --- missing topics and fields --------------------------------------------------------------------------------


def test_missing_topic_and_field(tmp_path):
    path = tmp_path / "att.ulg"
    _attitude_only(path=path)
    with pytest.raises(FlightDataError, match=r"att\.ulg: channel 'p' \(vehicle_angular_velocity\.xyz\[0\]: "
                                              r"no vehicle_angular_velocity messages in the log \(found: "
                                              r"vehicle_attitude\)\)"):
        load(path, channels={"p": ("vehicle_angular_velocity", "xyz[0]")}, missing_inputs="zero")
    with pytest.raises(FlightDataError, match=r"channel 'phi' \(vehicle_attitude\.roll\(quat\): message "
                                              r"vehicle_attitude has no field 'quat\[0\]' \(fields: timestamp, q\[0\]"):
        load(path, channels={"phi": ("vehicle_attitude", "roll(quat)")}, missing_inputs="zero")
    with pytest.raises(FlightDataError, match=r"channel 'lat' \(input_rc\.rc\(values\[0\]\): no input_rc messages.*"
                                              r"manual_control_setpoint\.y: no manual_control_setpoint.*"
                                              r"missing_inputs='zero'"):
        load(path)
    flight = load(path, missing_inputs="zero")  # default mapping: the outputs without topics are dropped
    assert flight.output_names == ("phi", "theta") and not flight.inputs.any()
    assert "no vehicle_local_position messages" in flight.metadata["dropped"]["u"]
    assert "sensor_combined.gyro_rad[0]: no sensor_combined messages" in flight.metadata["dropped"]["p"]
    np.testing.assert_allclose(flight.output("phi"), 0.01 * np.arange(20), atol=1e-6)


def test_velocity_without_attitude(tmp_path):
    tv = 0.01 * np.arange(10)
    path = tmp_path / "vel.ulg"
    path.write_bytes(ulog_bytes({"vehicle_local_position": {"timestamp": _stamps(tv), "vx": tv, "vy": tv, "vz": tv}}))
    with pytest.raises(FlightDataError, match=r"channel 'u' \(vehicle_local_position\.body_x\(vx,vy,vz\): no "
                                              r"vehicle_attitude messages"):
        load(path, channels={"u": DEFAULT_ULOG["u"]}, missing_inputs="zero")


# --- damaged and foreign files --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cut", "match"),
    [
        (0, r"empty file \(0 bytes\)"),
        (10, r"file truncated after 10 bytes \(shorter than the 16-byte ULog header\)"),
        (-7, r"file truncated after {n} bytes \(last complete message ends at byte {end}\); pass strict=False"),
    ],
)
def test_truncated(tmp_path, cut, match):
    data = _attitude_only()
    kept = data[:cut]
    path = tmp_path / "cut.ulg"
    path.write_bytes(kept)
    with pytest.raises(FlightDataError, match=r"cut\.ulg: " + match.format(n=len(kept), end=len(data) - 29)):
        load(path)


def test_truncated_loads_readable_part_when_not_strict(tmp_path):
    data = _attitude_only()
    path = tmp_path / "cut.ulg"
    path.write_bytes(data[:-7])
    flight = load(path, channels=ROLL, missing_inputs="zero", strict=False)
    assert flight.n_samples == 19
    assert flight.metadata["problems"] == [f"file truncated after {len(data) - 7} bytes (last complete message ends "
                                           f"at byte {len(data) - 29})"]


def test_definitions_only(tmp_path):
    path = tmp_path / "nodata.ulg"
    path.write_bytes(ulog_bytes({"vehicle_attitude": {"timestamp": _stamps([]), "q": np.zeros((0, 4))}}))
    with pytest.raises(FlightDataError, match=r"nodata\.ulg: no data messages after 1 format definitions"):
        load(path)


def test_corrupt_bytes(tmp_path):
    data = bytearray(_attitude_only())
    start = len(data) - 8 * 29  # a message boundary: 8 messages before the end
    data[start:start + 40] = bytes(40)
    path = tmp_path / "corrupt.ulg"
    path.write_bytes(bytes(data))
    with pytest.raises(FlightDataError, match=rf"corrupt\.ulg: corrupt: invalid message header \(type 0x00, 0 bytes\) "
                                              rf"at byte {start}"):
        load(path, channels=ROLL, missing_inputs="zero")
    flight = load(path, channels=ROLL, missing_inputs="zero", strict=False)
    assert 12 <= flight.n_samples < 20 and flight.metadata["problems"][0].startswith("corrupt")


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"time,lat\n0,1\n", r"not a ULog file: starts with bytes 74 69 6d 65 2c 6c 61, expected 55 4c 6f 67"),
        (b"\xa3\x95\x80" + bytes(200), "not a ULog file"),
    ],
)
def test_foreign_files(tmp_path, content, match):
    path = tmp_path / "foreign.ulg"
    path.write_bytes(content)
    with pytest.raises(FlightDataError, match=r"foreign\.ulg: " + match):
        load(path)


def test_incompatible_flags(tmp_path):
    data = bytearray(_attitude_only())
    data[16 + 3 + 8] = 0x02  # an incompat flag bit this format version does not define
    path = tmp_path / "flags.ulg"
    path.write_bytes(bytes(data))
    with pytest.raises(FlightDataError, match=r"flags\.ulg: cannot read the ULog: Unknown incompatible flag"):
        load(path)


def test_unknown_message_type_is_corruption(tmp_path):
    path = tmp_path / "odd.ulg"
    path.write_bytes(_attitude_only() + message("Z", b"\x00" * 5))
    with pytest.raises(FlightDataError, match=r"invalid message header \(type 0x5a, 5 bytes\)"):
        load(path, channels=ROLL, missing_inputs="zero")


def test_bad_options(tmp_path):
    path = tmp_path / "att.ulg"
    _attitude_only(path=path)
    for channels, match in (
        ({"yaw": ("vehicle_attitude", "yaw(q)")}, "channel 'yaw': unknown"),
        ({"phi": "vehicle_attitude.roll(q)"}, r"channel 'phi': expected \(topic, field\[, scale\[, offset\]\]\)"),
        ({"phi": []}, r"channel 'phi': expected"),
        ({"phi": ("vehicle_attitude", "roll(q,x)")}, r"channel 'phi': bad derived field 'roll\(q,x\)'"),
        ({"u": ("vehicle_local_position", "body_x(vx)")}, r"channel 'u': bad derived field 'body_x\(vx\)'"),
        ({"lat": ("input_rc", "rc(values)")}, r"channel 'lat': bad derived field 'rc\(values\)'"),
        ({"phi": ("vehicle_attitude", "spin(q)")}, r"channel 'phi': bad derived field 'spin\(q\)'"),
    ):
        with pytest.raises(FlightDataError, match=r"att\.ulg: " + match):
            load_ulog(path, channels)
    with pytest.raises(FlightDataError, match="option 'rate_hz': must be > 0 Hz"):
        load_ulog(path, rate_hz=-1)
    with pytest.raises(FlightDataError, match="option 'attitude'"):
        load_ulog(path, attitude="vehicle_attitude")
    with pytest.raises(FileNotFoundError, match=r"gone\.ulg"):
        load(tmp_path / "gone.ulg")


# --- the command line -----------------------------------------------------------------------------------------


def test_cli_evaluate_on_a_ulog(truth, truth_log, tmp_path, capsys):
    """``jaxheli evaluate`` takes a .ulg like any flight file; its metrics match those of the flight in memory."""
    from jaxheli.cli import main
    from jaxheli.evaluate import evaluate

    out = tmp_path / "metrics.json"
    assert main(["evaluate", "--model", "table2", "--data", str(truth_log), "--segment", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"table2 on {truth_log} ({truth.n_samples} samples, dt 0.01 s)" in printed
    block = json.loads(out.read_text())
    reference = evaluate("table2", truth, segment=1.0)
    assert list(block["pearson"]) == list(ALL_OUTPUTS)
    np.testing.assert_allclose([block["pearson"][c] for c in ALL_OUTPUTS],
                               [reference["pearson"][c] for c in ALL_OUTPUTS], atol=2e-3)
    assert block["cost"] == pytest.approx(reference["cost"], abs=2e-3)


def test_identify_and_diagnose_commands_take_a_ulog_like_a_px4log(truth, truth_log, shared_data, tmp_path):
    """The ``jaxheli identify`` command line that runs on a real .px4log runs unchanged on a .ulg (written by the
    test), and ``jaxheli diagnose`` takes the .ulg and the result. (That px4log's u and v are all zero;
    tests/test_diagnose.py checks that ``diagnose`` leaves such channels out. The .ulg reader's records equal
    the flight written, as the tests above check, so an NPZ copy would give the same numbers. The 4-s record takes
    2-s segments, and the filter restart: the reader path is the same, its predictor compiles in a third of the
    time.)"""
    from jaxheli.cli import main

    def identify(path, out):
        assert main(["identify", "--method", "iwo", "--train", str(path), "--iterations", "2", "--outputs",
                     "p,q,phi,theta", "--out", str(out)]) == 0
        return json.loads((out / "result.json").read_text())

    for path in (shared_data / "px4logs/sess006/log001.px4log", truth_log):
        result = identify(path, tmp_path / path.suffix[1:])
        assert result["settings"]["train_source"] == str(path)
        assert set(result["train"]["pearson"]) == {"p", "q", "phi", "theta"}
        assert all(np.isfinite(v) for v in result["train"]["pearson"].values())
    saved = load(tmp_path / "ulg" / "train_flight.npz")
    np.testing.assert_allclose(saved.outputs, truth.select(saved.output_names).outputs, atol=1e-5)
    assert main(["diagnose", "--model", str(tmp_path / "ulg" / "result.json"), "--train", str(truth_log),
                 "--validate", str(truth_log), "--effects", "output_bias_drift", "--max-steps", "3", "--top", "1",
                 "--restart", "filter", "--segment", "2", "--frozen-base", "--out", str(tmp_path / "diagnose")]) == 0
    diagnosis = json.loads((tmp_path / "diagnose" / "diagnosis.json").read_text())
    assert diagnosis["outputs"] == list(ALL_OUTPUTS)
    assert [e["effect"] for e in diagnosis["ranking"]] == ["output_bias_drift"]
    assert np.isfinite(diagnosis["ranking"][0]["shrink_pct"])
