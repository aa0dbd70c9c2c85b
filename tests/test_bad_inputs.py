"""The bad-input catalogue of issue 17: each case a clear one-line FlightDataError naming the file (exit 2 from
the CLI, no traceback) or a warning recorded in the flight's provenance."""

import json
import struct

import numpy as np
import pytest
import scipy.io
from pymavlink import DFReader

from jaxheli.cli import main
from jaxheli.data.flight import FlightDataError
from jaxheli.io import load, save_csv, save_npz
from jaxheli.synth.piloted import piloted_flight

STICKS = ("lat", "lon", "ped", "col")


@pytest.fixture(scope="module")
def flight():
    return piloted_flight(duration=30.0, dt=0.05, seed=3)


def _cli_error(capsys, argv, *needles):
    """Run the CLI; assert exit 2 and one stderr error line (besides any one-line notes; no traceback)
    containing every needle."""
    capsys.readouterr()
    assert main(argv) == 2
    lines = [line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith("note: ")]
    err = "\n".join(lines)
    assert len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def _csv(path, flight, edit=None):
    save_csv(flight, path)
    if edit:
        lines = path.read_text().splitlines()
        edit(lines)
        path.write_text("\n".join(lines) + "\n")
    return path


def _set_cell(row, column):
    def edit(lines):
        header = lines[0].split(",")
        cells = lines[row].split(",")
        cells[header.index(column)] = "1e300"
        lines[row] = ",".join(cells)
    return edit


def test_char_element_with_unknown_type_is_refused_not_a_segfault(tmp_path, capsys):
    """One changed byte in an uncompressed MAT-v5 file: the small tag of a char element turned to type 200."""
    path = tmp_path / "char.mat"
    rng = np.random.default_rng(0)
    scipy.io.savemat(path, {"label": "ab", "inr": rng.normal(size=(20, 4)), "outr": rng.normal(size=(20, 10)),
                            "t": np.arange(20) * 0.01})
    data = bytearray(path.read_bytes())
    at = bytes(data).index(struct.pack("<HH", 16, 2) + b"ab")  # small miUTF8 element of the char array
    data[at] = 200
    path.write_bytes(bytes(data))
    with pytest.raises(FlightDataError, match=r"char\.mat: not a readable MATLAB file: corrupt.*unknown data type 200"):
        load(path)
    _cli_error(capsys, ["evaluate", "--model", "table2", "--data", str(path)], "char.mat", "unknown data type")


def test_foreign_reader_exception_becomes_the_library_error(tmp_path, monkeypatch, flight):
    def broken(*args, **kwargs):
        raise UnboundLocalError("cannot access local variable 'res'")

    path = tmp_path / "x.mat"
    scipy.io.savemat(path, {"inr": flight.inputs, "outr": np.zeros((flight.n_samples, 10)), "t": flight.time})
    monkeypatch.setattr(scipy.io, "loadmat", broken)
    with pytest.raises(FlightDataError, match=r"x\.mat: the MATLAB reader failed: UnboundLocalError: cannot access"):
        load(path)


def test_directory_is_not_called_missing(tmp_path, capsys):
    folder = tmp_path / "flights.csv"
    folder.mkdir()
    with pytest.raises(FlightDataError, match="flights.csv: is a directory"):
        load(folder)
    _cli_error(capsys, ["evaluate", "--model", "table2", "--data", str(folder)], "is a directory")


def test_npz_error_names_the_path_read(tmp_path, flight):
    path = tmp_path / "read_me.npz"
    save_npz(flight.replace(source="somewhere/else.csv"), path)
    arrays = dict(np.load(path))
    arrays["time"] = arrays["time"][::-1].copy()
    np.savez(path, **arrays)
    with pytest.raises(FlightDataError, match=r"^\S*read_me\.npz: stored flight invalid: .*field 'time'"):
        load(path)


def test_implausible_npz_names_the_path_read(tmp_path, flight):
    path = tmp_path / "read_me.npz"
    save_npz(flight.replace(source="somewhere/else.csv", time=flight.time * 200.0), path)
    with pytest.raises(FlightDataError, match=r"^\S*read_me\.npz: field 'time': sample time 10 s"):
        load(path)


def test_iddata_ts_string_names_file_and_field(tmp_path, flight):
    path = tmp_path / "ts.mat"
    scipy.io.savemat(path, {"exp": {"OutputData": flight.outputs, "InputData": flight.inputs, "Ts": "0.02"}})
    with pytest.raises(FlightDataError, match=r"ts\.mat: field 'exp\.Ts': expected a real number"):
        load(path)


def test_pymavlink_chatter_is_captured_not_printed(shared_data, tmp_path, capsys):
    data = (shared_data / "px4logs" / "2016-08-09" / "13_25_39.px4log").read_bytes()
    path = tmp_path / "noisy.px4log"
    path.write_bytes(data[:200_000] + bytes(range(7, 107)) + data[200_000:])
    capsys.readouterr()
    with pytest.raises(FlightDataError, match=r"noisy\.px4log: corrupt.*parser printed .*Skipped"):
        load(path)
    flight = load(path, strict=False)
    assert any("Skipped" in w for w in flight.metadata["warnings"])
    printed = capsys.readouterr()
    assert printed.out == "" and printed.err == ""


@pytest.mark.parametrize("column", ["p", "col"])
def test_huge_csv_cell_names_file_channel_and_row(tmp_path, capsys, flight, column):
    path = _csv(tmp_path / "huge.csv", flight, _set_cell(7, column))
    with pytest.raises(FlightDataError, match=rf"huge\.csv: .*channel '{column}'.*first 1e\+300 at row 6"):
        load(path)
    _cli_error(capsys, ["evaluate", "--model", "table2", "--data", str(path)], f"channel '{column}'", "--no-strict")
    kept = load(path, strict=False)
    assert any(f"channel '{column}'" in w for w in kept.metadata["warnings"])


def test_huge_mat_value(tmp_path, flight):
    outr = np.zeros((flight.n_samples, 10))
    outr[:, 2] = flight.output("p")
    outr[9, 2] = 1e300
    path = tmp_path / "huge.mat"
    scipy.io.savemat(path, {"inr": flight.inputs, "outr": outr, "t": flight.time})
    with pytest.raises(FlightDataError, match=r"huge\.mat: field 'outputs' channel 'p'.*1e\+300 at row 9"):
        load(path)


def test_time_in_milliseconds(tmp_path, capsys, flight):
    path = _csv(tmp_path / "ms.csv", flight.replace(time=flight.time * 200.0))
    with pytest.raises(FlightDataError, match=r"ms\.csv: field 'time': sample time 10 s .*milliseconds"):
        load(path)
    _cli_error(capsys, ["evaluate", "--model", "table2", "--data", str(path)], "milliseconds")


def test_two_row_csv(tmp_path, capsys, flight):
    path = tmp_path / "short.csv"
    save_csv(flight, path)
    path.write_text("\n".join(path.read_text().splitlines()[:3]) + "\n")
    with pytest.raises(FlightDataError, match=r"short\.csv: field 'time': 2 samples; need at least 10"):
        load(path)
    _cli_error(capsys, ["evaluate", "--model", "table2", "--data", str(path)], "2 samples")


def test_outr_layout_not_guessed_from_the_column_count(tmp_path, flight):
    path = tmp_path / "ten.mat"
    rng = np.random.default_rng(1)
    scipy.io.savemat(path, {"inr": flight.inputs, "outr": rng.normal(size=(flight.n_samples, 10)), "t": flight.time})
    with pytest.raises(FlightDataError, match=r"ten\.mat: variable 'outr': 10 columns suggest the 'graphready'.*"
                                              r"column 7 \('a'\) is not a multiple of the 'lon' stick"):
        load(path)


@pytest.mark.parametrize("writer", ["mat", "npz"])
def test_complex_inputs_refused(tmp_path, flight, writer):
    inputs = flight.inputs + 0.5j
    path = tmp_path / f"cplx.{writer}"
    if writer == "mat":
        outr = np.zeros((flight.n_samples, 10))
        scipy.io.savemat(path, {"inr": inputs, "outr": outr, "t": flight.time})
    else:
        save_npz(flight, path)
        arrays = dict(np.load(path))
        np.savez(path, **{**arrays, "inputs": inputs})
    with pytest.raises(FlightDataError, match=r"cplx\.\w+: .*complex values"):
        load(path)


def test_px4log_cut_leaving_a_bare_record_header(shared_data, tmp_path, capsys):
    source = shared_data / "px4logs" / "2016-09-08" / "09_16_59.px4log"
    reader = DFReader.DFReader_binary(str(source))
    ends = []
    while reader.recv_msg() is not None:
        ends.append(reader.offset)
    reader.close()
    cut = ends[len(ends) // 2] + 3
    path = tmp_path / "cut.px4log"
    path.write_bytes(source.read_bytes()[:cut])
    with pytest.raises(FlightDataError, match=rf"cut\.px4log: file truncated after {cut} bytes"):
        load(path)
    _cli_error(capsys, ["evaluate", "--model", "table2", "--data", str(path)], "truncated", "--no-strict")


def test_all_zero_csv_channel_left_out_with_a_note(tmp_path, capsys, flight):
    zeroed = flight.outputs.copy()
    zeroed[:, flight.output_names.index("u")] = 0.0
    path = _csv(tmp_path / "flat.csv", flight.replace(outputs=zeroed))
    loaded = load(path)
    assert loaded.metadata["warnings"] == ["channel(s) u constant: left out of the default channel set"]
    assert load(save_npz(loaded, tmp_path / "flat.npz")).metadata["warnings"] == loaded.metadata["warnings"]
    capsys.readouterr()
    scores = tmp_path / "scores.json"
    assert main(["evaluate", "--model", "table2", "--data", str(path), "--x0", "zero", "--out", str(scores)]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("note:") == 1 and "u constant" in captured.err
    assert set(json.loads(scores.read_text())["pearson"]) == set(flight.output_names) - {"u"}
    _cli_error(capsys, ["evaluate", "--model", "table2", "--data", str(path), "--outputs", "u,p"],
               "flat.csv", "channel(s) u constant")


def test_missing_inputs_flag(shared_data, tmp_path, capsys):
    path = shared_data / "px4logs" / "reference" / "log001.bin"
    _cli_error(capsys, ["check", "--data", str(path), "--out", str(tmp_path)], "log001.bin", "--missing-inputs zero")
    assert main(["check", "--data", str(path), "--missing-inputs", "zero", "--out", str(tmp_path)]) == 0


def test_no_strict_flag_loads_a_truncated_log(shared_data, tmp_path, capsys):
    path = tmp_path / "cut.px4log"
    path.write_bytes((shared_data / "px4logs" / "2016-08-09" / "13_25_39.px4log").read_bytes()[:300_001])
    _cli_error(capsys, ["check", "--data", str(path), "--out", str(tmp_path)], "truncated", "--no-strict")
    assert main(["check", "--data", str(path), "--no-strict", "--out", str(tmp_path)]) == 0


def test_channel_map_file(shared_data, tmp_path, capsys):
    path = shared_data / "px4logs" / "reference" / "log001.bin"
    mapping = tmp_path / "map.json"
    mapping.write_text(json.dumps({"p": ["ATT", "RollRate"], "q": ["ATT", "PitchRate", 1.0], "r": ["ATT", "YawRate"]}))
    assert main(["check", "--data", str(path), "--channel-map", str(mapping), "--missing-inputs", "zero",
                 "--out", str(tmp_path)]) == 0
    assert (tmp_path / "consistency.json").is_file()
    mapping.write_text("{not json")
    _cli_error(capsys, ["check", "--data", str(path), "--channel-map", str(mapping), "--out", str(tmp_path)],
               "map.json: not a JSON channel map")
    _cli_error(capsys, ["check", "--data", str(path), "--channel-map", str(tmp_path / "none.json"), "--out", str(tmp_path)],
               "none.json: no such channel-map file")
