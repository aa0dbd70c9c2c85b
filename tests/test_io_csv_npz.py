"""CSV and NPZ readers/writers: exact round trips, format dispatch, and a clear error for every bad input."""

import json

import numpy as np
import pytest

from jaxheli import flights
from jaxheli.data.flight import FlightData, FlightDataError
from jaxheli.io import load, load_csv, load_npz, save, save_csv, save_npz

HEADER = "time,lat,lon,ped,col,p,q"


def _write(tmp_path, text, name="f.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _flight():
    t = 0.5 + 0.01 * np.arange(50)
    rng = np.random.default_rng(1)
    return FlightData(t, rng.normal(size=(50, 4)), rng.normal(size=(50, 3)), ("phi", "u", "r"), "synthetic",
                      {"note": "x", "preprocessing": [{"step": "lowpass", "cutoff_hz": 2.0}]})


def _assert_same(a, b):
    np.testing.assert_array_equal(a.time, b.time)
    np.testing.assert_array_equal(a.inputs, b.inputs)
    np.testing.assert_array_equal(a.outputs, b.outputs)
    assert a.output_names == b.output_names


def test_csv_round_trip_real_flight(shared_data, tmp_path):
    flight = load(shared_data / "trex550" / "ppr_data.mat")
    back = load(save_csv(flight, tmp_path / "ppr.csv"))
    _assert_same(flight, back)
    assert back.metadata == {"reader": "csv", "file": str(tmp_path / "ppr.csv"), "ignored_columns": []}


def test_csv_keeps_column_order_and_ignores_extra_columns(tmp_path):
    text = "time, mode ,q,lat,lon,ped,col,p,AccZ\n" + "\n".join(
        f"{k * 0.1:.1f},hover,{k},1,2,3,4,{2 * k},-9.8" for k in range(12))
    flight = load_csv(_write(tmp_path, text))
    assert flight.output_names == ("q", "p")
    np.testing.assert_array_equal(flight.output("p"), 2 * np.arange(12))
    np.testing.assert_array_equal(flight.inputs[0], [1, 2, 3, 4])
    assert flight.metadata["ignored_columns"] == ["mode", "AccZ"]


def test_csv_uneven_stamps_resampled_on_request(tmp_path):
    t = np.array([0.0, 0.013, 0.019, 0.032, 0.04, 0.051, 0.06, 0.068, 0.081, 0.09, 0.1, 0.112])
    text = HEADER + "\n" + "\n".join(f"{x},{x},0,0,0,{3 * x + 1},{-x}" for x in t)
    path = _write(tmp_path, text)
    with pytest.raises(FlightDataError, match=r"f\.csv: field 'time': uneven sampling"):
        load_csv(path)
    flight = load_csv(path, dt=0.01)
    np.testing.assert_allclose(flight.time, 0.01 * np.arange(12), atol=1e-15)
    np.testing.assert_allclose(flight.output("p"), 3 * flight.time + 1, atol=1e-12)  # linear data: exact
    assert flight.metadata["preprocessing"][0]["step"] == "from_samples"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("", r"f\.csv: empty file"),
        ("time,lat,lon,ped,p\n0,0,0,0,0\n0.1,0,0,0,0", r"line 1: missing column\(s\) \['col'\]"),
        ("lat,lon,ped,col,p\n0,0,0,0,0\n0,0,0,0,0", r"line 1: missing column\(s\) \['time'\]"),
        ("time,lat,lon,ped,col,AccZ\n0,0,0,0,0,0\n0.1,0,0,0,0,0", "no output column"),
        ("time,lat,lon,ped,col,p,p\n0,0,0,0,0,0,0", r"duplicated column\(s\) \['p'\]"),
        (HEADER + "\n0,0,0,0,0,0,0\n0.01,0,0,0,0,abc,0\n", r"line 3, column 'p': not a number: 'abc'"),
        (HEADER + "\n0,0,0,0,0,0,0\n0.01,0,0,0,,0,0\n", r"line 3, column 'col': not a number: ''"),
        (HEADER + "\n0,0,0,0,0,0,0\n0.01,0,0,0,0,0,0\n0.02,0,0,0,0,0,nan\n", r"line 4, column 'q': non-finite"),
        (HEADER + "\n0,0,0,0,0,0,0\n0.01,0,0,0,0,inf,0\n", r"line 3, column 'p': non-finite"),
        (HEADER + "\n0,0,0,0,0,0,0\n0.01,0,0,0,0,0\n", r"line 3: 6 cells, but the header has 7 columns"),
        (HEADER + "\n0,0,0,0,0,0,0\n0.01,0,0,0,0,0,0,7\n", r"line 3: 8 cells"),
        (HEADER + "\n0,0,0,0,0,0,0\n0.02,0,0,0,0,0,0\n0.01,0,0,0,0,0,0\n",
         r"line 4, column 'time': 0.01 s does not increase \(previous 0.02 s\)"),
        (HEADER + "\n0,0,0,0,0,0,0\n\n0,0,0,0,0,0,0\n", r"line 4, column 'time'.*does not increase"),
        (HEADER + "\n0,0,0,0,0,0,0\n", "1 data rows; need at least 2"),
    ],
)
def test_csv_errors(tmp_path, text, match):
    with pytest.raises(FlightDataError, match=match):
        load(_write(tmp_path, text))


def test_csv_binary_garbage(tmp_path):
    path = tmp_path / "g.csv"
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(FlightDataError, match=r"g\.csv: not a text CSV file"):
        load(path)


def test_csv_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"absent\.csv"):
        load_csv(tmp_path / "absent.csv")


def test_npz_round_trip_with_metadata(tmp_path):
    flight = _flight().replace(metadata={**_flight().metadata, "gain": np.float64(2.5), "arr": np.arange(3)})
    back = load(save_npz(flight, tmp_path / "f.npz"))
    _assert_same(flight, back)
    assert back.source == "synthetic"
    assert back.metadata == {"note": "x", "preprocessing": [{"step": "lowpass", "cutoff_hz": 2.0}],
                             "gain": 2.5, "arr": [0, 1, 2]}


def test_npz_round_trip_real_flight(shared_data, tmp_path):
    flight = load(shared_data / "trex550" / "tested.mat")
    back = load_npz(save_npz(flight, tmp_path / "tested.npz"))
    _assert_same(flight, back)
    assert back.metadata == json.loads(json.dumps(flight.metadata))


def test_npz_errors(tmp_path):
    garbage = tmp_path / "g.npz"
    garbage.write_bytes(b"not a zip archive at all" * 10)
    with pytest.raises(FlightDataError, match=r"g\.npz: not a readable NPZ"):
        load(garbage)
    partial = tmp_path / "partial.npz"
    np.savez(partial, time=np.arange(3.0), inputs=np.zeros((3, 4)))
    with pytest.raises(FlightDataError, match=r"partial\.npz: field 'outputs' not found"):
        load(partial)
    single = tmp_path / "single.npy"
    np.save(single, np.arange(3))
    renamed = single.rename(tmp_path / "single.npz")
    with pytest.raises(FlightDataError, match="single .npy array"):
        load(renamed)
    shapes = tmp_path / "shapes.npz"
    np.savez(shapes, time=np.arange(3.0), inputs=np.zeros((3, 3)), outputs=np.zeros((3, 1)),
             output_names=np.array(["p"]), source=np.array("s"), metadata=np.array("{}"))
    with pytest.raises(FlightDataError, match=r"field 'inputs': expected shape \(3, 4\)"):
        load(shapes)


def test_load_sniffs_content_without_extension(tmp_path):
    flight = _flight()
    npz = save_npz(flight, tmp_path / "flight_a")
    _assert_same(flight, load(npz))
    csv = save_csv(flight, tmp_path / "flight_b")
    _assert_same(flight, load(csv))


def test_load_unknown_format(tmp_path):
    path = _write(tmp_path, "hello world\n", name="notes.txt")
    with pytest.raises(FlightDataError, match=r"notes\.txt: unknown flight-data format.*'\.txt'.*supported"):
        load(path)
    with pytest.raises(FileNotFoundError, match=r"missing\.bin"):
        load(tmp_path / "missing.bin")


@pytest.mark.parametrize("name, head", [("f.npz", b"PK"), ("f.NPZ", b"PK"), ("f.csv", b"time"), ("f.txt", b"time")])
def test_save_picks_the_writer_by_extension_and_load_flight_reads_it(tmp_path, name, head):
    path = save(_flight(), tmp_path / name)
    assert path == tmp_path / name and path.read_bytes().startswith(head)
    _assert_same(_flight(), flights.load_flight(str(path)))


def test_load_flight_default_is_the_embedded_flight(monkeypatch, tmp_path):
    embedded = _flight()
    monkeypatch.setattr(flights, "default_flight", lambda: embedded)
    assert flights.load_flight(flights.DEFAULT_DATA) is embedded
    with pytest.raises(FileNotFoundError, match="no such flight-data file"):
        flights.load_flight(tmp_path / "default")
