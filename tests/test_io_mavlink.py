"""PX4 sdlog2 / DataFlash logs: the four real logs, synthetic logs with known content, and damaged copies."""

import struct

import numpy as np
import pytest
from pymavlink import mavutil

from jaxheli.data.flight import FlightDataError
from jaxheli.io import DEFAULT_PX4, load, load_log

ALL_OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
SMALL = "px4logs/2016-09-08/09_16_59.px4log"
BENCH = "px4logs/2016-08-09/13_25_39.px4log"

# --- a minimal DataFlash writer for logs with known content ------------------------------------------------


def _fmt(type_id: int, name: str, fmt: str, columns: str) -> bytes:
    length = 3 + struct.calcsize("<" + fmt)
    return b"\xa3\x95\x80" + struct.pack("<BB4s16s64s", type_id, length, name.encode(), fmt.encode(), columns.encode())


def _rec(type_id: int, fmt: str, *values) -> bytes:
    return b"\xa3\x95" + bytes([type_id]) + struct.pack("<" + fmt, *values)


_HEAD = (_fmt(1, "TIME", "Q", "StartTime") + _fmt(2, "ATT", "ffffff", "Roll,Pitch,Yaw,RollRate,PitchRate,YawRate")
         + _fmt(3, "RC", "ffffff", "C0,C1,C2,C3,C4,C5"))


def _sdlog(path, roll, start_us=None, rc_every=2):
    """TIME at 100 Hz with one ATT record per cycle (Roll = roll[k], RollRate = k) and RC every rc_every cycles."""
    start_us = 5_000_000 + 10_000 * np.arange(len(roll)) if start_us is None else start_us
    body = bytearray(_HEAD)
    for k, (t_us, phi) in enumerate(zip(start_us, roll)):
        body += _rec(1, "Q", int(t_us)) + _rec(2, "ffffff", phi, 0.1, 0, k, 0, 0)
        if k % rc_every == 0:
            body += _rec(3, "ffffff", 0.5, -0.5, 0, 0.25, 0, k / 100)
    path.write_bytes(bytes(body))
    return path


SYNTH = {"phi": ("ATT", "Roll"), "theta": ("ATT", "Pitch"), "p": ("ATT", "RollRate"),
         "lat": ("RC", "C0"), "lon": ("RC", "C1"), "ped": ("RC", "C3"), "col": ("RC", "C5")}

# --- real logs -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "n", "duration"),
    [(SMALL, 45, 0.351), (BENCH, 1310, 10.49), ("px4logs/sess006/log001.px4log", 3593, 28.77)],
)
def test_real_px4logs_load_with_default_mapping(shared_data, name, n, duration):
    flight = load(shared_data / name)
    assert (flight.n_samples, flight.output_names) == (n, ALL_OUTPUTS)
    assert flight.dt == pytest.approx(0.008, abs=5e-5)  # ATT at 125 Hz
    assert flight.duration == pytest.approx(duration, abs=0.01)
    assert np.abs(flight.inputs).max() <= 1.0
    assert flight.metadata["dropped"] == {} and flight.metadata["problems"] == []
    assert flight.metadata["channels"]["col"] == "RC.C5"


def test_bench_log_against_independent_parse(shared_data):
    """Roll and stick values on the grid equal a direct pymavlink read, stamped by the latest TIME record."""
    path = shared_data / BENCH
    flight = load_log(path)
    conn = mavutil.mavlink_connection(str(path))
    clock, origin, att, rc = None, None, [], []
    while (msg := conn.recv_msg()) is not None:
        kind = msg.get_type()
        if kind == "TIME":
            clock = msg.StartTime * 1e-6
            origin = clock if origin is None else origin
        elif kind == "ATT":
            att.append((clock - origin, msg.Roll))
        elif kind == "RC":
            rc.append((clock - origin, msg.C3))
    conn.close()
    att, rc = np.array(att), np.array(rc)
    np.testing.assert_allclose(flight.output("phi"), np.interp(flight.time, *att.T), atol=1e-12)
    np.testing.assert_allclose(flight.inputs[:, 2], np.interp(flight.time, *rc.T), atol=1e-12)
    assert np.ptp(flight.inputs[:, 2]) > 1 and np.ptp(flight.inputs[:, 3]) > 0.5  # RC channels 4 and 6 moved
    assert np.ptp(flight.inputs[:, 0]) == 0


def test_reference_bin_needs_inputs(shared_data):
    path = shared_data / "px4logs/reference/log001.bin"
    with pytest.raises(FlightDataError, match=r"log001\.bin: channel 'lat' \(RC\.C0\): no RC messages.*missing_inputs"):
        load(path)
    flight = load(path, missing_inputs="zero")
    assert flight.output_names == ("p", "q", "phi", "theta", "r")
    assert flight.n_samples == 2734 and flight.dt == pytest.approx(0.0201, abs=1e-4)  # ATT at ~49.8 Hz
    assert flight.duration == pytest.approx(54.9, abs=0.1)
    assert not flight.inputs.any()
    assert set(flight.metadata["dropped"]) == {"u", "v", "w", "lat", "lon", "ped", "col"}
    assert "no LPOS messages" in flight.metadata["dropped"]["u"]
    assert flight.metadata["zero_inputs"] == ["lat", "lon", "ped", "col"]
    assert np.abs(flight.output("phi")).max() <= np.pi


def test_explicit_mapping_requires_every_channel(shared_data):
    path = shared_data / "px4logs/reference/log001.bin"
    with pytest.raises(FlightDataError, match=r"log001\.bin: channel 'u' \(LPOS\.VY\): no LPOS messages"):
        load_log(path, channels=DEFAULT_PX4, missing_inputs="zero")
    with pytest.raises(FlightDataError, match=r"channel 'p' \(ATT\.GX\): message ATT has no field 'GX'"):
        load_log(path, channels={"p": ("ATT", "GX")}, missing_inputs="zero")
    with pytest.raises(FlightDataError, match=r"input 'lat' has no mapping"):
        load_log(path, channels={"p": ("ATT", "RollRate")})
    flight = load_log(path, channels={"p": ("ATT", "RollRate", 2.0)}, missing_inputs="zero", rate_hz=20)
    assert flight.output_names == ("p",) and flight.dt == pytest.approx(0.05)
    assert flight.metadata["channels"] == {"p": "ATT.RollRate x 2"}


# --- synthetic logs ------------------------------------------------------------------------------------------


def test_synthetic_log_exact_values(tmp_path):
    roll = 0.01 * np.arange(40)
    flight = load(_sdlog(tmp_path / "s.px4log", roll), channels=SYNTH)
    np.testing.assert_allclose(flight.time, 0.01 * np.arange(39), atol=1e-12)  # RC ends at cycle 38
    np.testing.assert_allclose(flight.output("phi"), roll[:39], atol=1e-6)
    np.testing.assert_allclose(flight.output("p"), np.arange(39), atol=1e-9)
    np.testing.assert_allclose(flight.inputs[:, 3], flight.time, atol=1e-6)  # C5 = k / 100 at t = k / 100
    np.testing.assert_allclose(flight.inputs[:, :3], np.tile([0.5, -0.5, 0.25], (39, 1)))


def test_roll_interpolated_across_the_pi_seam(tmp_path):
    roll = np.where(np.arange(20) % 2 == 0, 3.1, -3.1)  # +-3.1 rad alternating: 0.08 rad apart through pi
    flight = load(_sdlog(tmp_path / "seam.px4log", roll, rc_every=1), channels=SYNTH, rate_hz=400)
    assert np.abs(flight.output("phi")).min() >= 3.1 - 1e-6


@pytest.mark.parametrize("start_us", [[1000, 2000, 1500, 3000], [1000, 1000, 1000, 1000]])
def test_bad_time_stamps(tmp_path, start_us):
    path = _sdlog(tmp_path / "t.px4log", np.zeros(4), start_us=start_us, rc_every=1)
    match = "time stamps go backwards" if start_us[2] < start_us[1] else "ATT messages carry 1 distinct time stamp"
    with pytest.raises(FlightDataError, match=match):
        load(path, channels=SYNTH)


def test_timeus_messages_use_their_own_clock(tmp_path):
    """ArduPilot-style records carry TimeUS; no TIME record is needed."""
    head = _fmt(4, "ATT", "Qff", "TimeUS,Roll,Pitch") + _fmt(5, "RCIN", "Qff", "TimeUS,C1,C2")
    body = b"".join(_rec(4, "Qff", 2_000_000 + 20_000 * k, 0.01 * k, 0) + _rec(5, "Qff", 2_000_000 + 20_000 * k, 1, 2)
                    for k in range(10))
    path = tmp_path / "ardu.bin"
    path.write_bytes(head + body)
    flight = load(path, channels={"phi": ("ATT", "Roll"), "lat": ("RCIN", "C1"), "lon": ("RCIN", "C2")},
                  missing_inputs="zero")
    assert flight.dt == pytest.approx(0.02) and flight.n_samples == 10
    np.testing.assert_allclose(flight.output("phi"), 0.5 * flight.time, atol=1e-6)
    assert flight.metadata["zero_inputs"] == ["ped", "col"]


# --- damaged files -----------------------------------------------------------------------------------------


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"gone\.px4log"):
        load(tmp_path / "gone.px4log")


@pytest.mark.parametrize(
    ("cut", "match"),
    [
        (0, r"empty file \(0 bytes\)"),
        (2, "file truncated after 2 bytes"),
        (50, r"file truncated after 50 bytes \(shorter than one FMT record\)"),
        (5340, "no data records after 60 FMT definitions in 5340 bytes"),
        (20000, r"file truncated after 20000 bytes \(last complete record ends at byte 19982\)"),
        (39050, "file truncated after 39050 bytes"),
    ],
)
def test_truncated_copies(shared_data, tmp_path, cut, match):
    path = tmp_path / "cut.px4log"
    path.write_bytes((shared_data / SMALL).read_bytes()[:cut])
    with pytest.raises(FlightDataError, match=r"cut\.px4log: " + match):
        load(path)


def test_truncated_copy_loads_readable_part_when_not_strict(shared_data, tmp_path):
    path = tmp_path / "cut.px4log"
    path.write_bytes((shared_data / SMALL).read_bytes()[:39000])
    flight = load(path, strict=False)
    assert flight.n_samples == 44
    assert flight.metadata["problems"] == ["file truncated after 39000 bytes (last complete record ends at byte 38996)"]


def test_corrupt_bytes_detected(shared_data, tmp_path):
    data = bytearray((shared_data / SMALL).read_bytes())
    data[30000:30100] = bytes(100)
    path = tmp_path / "corrupt.px4log"
    path.write_bytes(bytes(data))
    with pytest.raises(FlightDataError, match=r"corrupt\.px4log: corrupt: \d+ bytes could not be decoded, first at"):
        load(path)
    flight = load(path, strict=False)
    assert flight.n_samples == 45 and "corrupt" in flight.metadata["problems"][0]


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (np.random.default_rng(3).integers(0, 256, 4000, dtype=np.uint8).tobytes(), "not a DataFlash/sdlog2 log"),
        (b"time,lat\n0,1\n", r"not a DataFlash/sdlog2 log: starts with bytes 74 69 6d"),
        (b"\xa3\x95\x80" + np.random.default_rng(3).integers(0, 256, 3000, dtype=np.uint8).tobytes(),
         "corrupt log: pymavlink could not index it"),
    ],
)
def test_garbage_files(tmp_path, content, match):
    path = tmp_path / "garbage.bin"
    path.write_bytes(content)
    with pytest.raises(FlightDataError, match=r"garbage\.bin: " + match):
        load(path)


def test_bad_options(shared_data):
    path = shared_data / SMALL
    with pytest.raises(FlightDataError, match="channel 'yaw': unknown"):
        load_log(path, channels={"yaw": ("ATT", "Yaw")})
    with pytest.raises(FlightDataError, match=r"channel 'p': expected \(message, field\[, scale\]\)"):
        load_log(path, channels={"p": "ATT.RollRate"})
    with pytest.raises(FlightDataError, match="option 'rate_hz': must be > 0 Hz"):
        load_log(path, rate_hz=0)
