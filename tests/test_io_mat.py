"""The MATLAB reader against the authors' files (shapes and values per data/README.md) and bad inputs."""

import numpy as np
import pytest
import scipy.io

from jaxheli.data.flight import FlightDataError
from jaxheli.io import load, load_mat


def test_ppr_data_iddata(shared_data):
    path = shared_data / "trex550" / "ppr_data.mat"
    flight = load(path)
    raw = scipy.io.loadmat(path)["ppr_data"][0, 0]
    outputs, inputs = raw["OutputData"][0, 0], raw["InputData"][0, 0]
    assert flight.n_samples == 861
    assert flight.dt == pytest.approx(0.0081, abs=1e-12)
    assert flight.time[0] == pytest.approx(149.8824)
    assert flight.output_names == ("u", "v", "p", "q", "phi", "theta", "w", "r")
    np.testing.assert_array_equal(flight.outputs, outputs)
    np.testing.assert_array_equal(flight.inputs, inputs)
    assert np.abs(flight.inputs[:, 2]).max() < 1e-15  # the ped column is zero
    assert flight.output("phi").mean() == pytest.approx(0.42, abs=0.01)
    meta = flight.metadata
    assert meta["reader"] == "mat" and meta["layout"] == "iddata" and meta["Ts"] == 0.0081
    assert meta["variables"] == {"iddata": "ppr_data"}
    assert "mydata1 = mydata([18505:19365])" in meta["notes"]


def test_graphready_plain_arrays(shared_data):
    path = shared_data / "trex550" / "Data_graphready.mat"
    raw = scipy.io.loadmat(path)
    flight = load_mat(path)
    assert flight.n_samples == 8590
    assert flight.dt == pytest.approx(0.01, abs=1e-12)
    assert flight.output_names == ("u", "v", "p", "q", "phi", "theta", "w", "r")
    np.testing.assert_array_equal(flight.outputs, raw["outr"][:, [0, 1, 2, 3, 4, 5, 8, 9]])
    assert flight.metadata["dropped_columns"] == ["a", "b"]
    with_ab = load_mat(path, include_flapping=True)
    np.testing.assert_allclose(with_ab.output("a"), -6.8 * with_ab.inputs[:, 1], atol=1e-9)
    np.testing.assert_allclose(with_ab.output("b"), -6.8 * with_ab.inputs[:, 0], atol=1e-9)


def test_tested_column_order(shared_data):
    """tested.mat stores theta phi q p in other columns; rows 4136-12725 match Data_graphready.mat."""
    tested = load(shared_data / "trex550" / "tested.mat")
    assert tested.n_samples == 13622
    assert tested.dt == pytest.approx(0.01, abs=1e-12)
    assert (tested.time[0], tested.time[-1]) == pytest.approx((0.0, 136.21))
    assert tested.output_names == ("u", "v", "p", "q", "phi", "theta", "r")
    assert tested.metadata["dropped_columns"] == ["a", "b", "AccZ", "r_fb"]
    graph = load(shared_data / "trex550" / "Data_graphready.mat")
    seg = slice(4135, 12725)
    for name in ("u", "v", "phi", "theta"):
        rho = np.corrcoef(tested.output(name)[seg], graph.output(name))[0, 1]
        assert rho > 0.99, name
    ab = load_mat(shared_data / "trex550" / "tested.mat", include_flapping=True)
    np.testing.assert_allclose(ab.output("a"), -6.9 * ab.inputs[:, 1], atol=1e-9)


def test_variables_override_reads_model_outputs(shared_data):
    path = shared_data / "trex550" / "Data_graphready.mat"
    flight = load_mat(path, variables={"inputs": "inr", "outputs": "iwo", "time": "t"},
                      columns=("u", "v", "p", "q", "phi", "theta", "r"))
    np.testing.assert_array_equal(flight.outputs, scipy.io.loadmat(path)["iwo"])
    assert flight.metadata["layout"] == "custom"


def test_iddata_struct_under_any_name(tmp_path):
    rng = np.random.default_rng(0)
    out, inp = rng.normal(size=(20, 8)), rng.normal(size=(20, 4))
    path = tmp_path / "mine.mat"
    scipy.io.savemat(path, {"exp": {"OutputData": out, "InputData": inp, "Ts": 0.02, "Tstart": 1.0}})
    flight = load(path)
    assert flight.metadata["variables"] == {"iddata": "exp"}
    assert flight.time[0] == 1.0 and flight.dt == pytest.approx(0.02)
    np.testing.assert_array_equal(flight.outputs, out)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.mat"):
        load(tmp_path / "nope.mat")


def test_unknown_layout_names_file_and_variable(shared_data):
    with pytest.raises(FlightDataError, match=r"Record\.mat: variable 'inr' not found.*ptot"):
        load(shared_data / "trex550" / "Record.mat")


def test_override_with_missing_variable(shared_data):
    with pytest.raises(FlightDataError, match=r"ppr_data\.mat: variable 'inr' \(inputs\) not found"):
        load_mat(shared_data / "trex550" / "ppr_data.mat", variables={"inputs": "inr", "outputs": "outr", "time": "t"})


def test_not_a_mat_file(tmp_path):
    path = tmp_path / "junk.mat"
    path.write_bytes(b"definitely not MATLAB" * 20)
    with pytest.raises(FlightDataError, match=r"junk\.mat: not a readable MATLAB"):
        load(path)


@pytest.mark.parametrize(
    ("arrays", "match"),
    [
        ({"inr": np.zeros((5, 3)), "outr": np.zeros((5, 10)), "t": np.arange(5.0)}, r"variable 'inr'.*\[N, 4\]"),
        ({"inr": np.zeros((5, 4)), "outr": np.zeros((6, 10)), "t": np.arange(5.0)}, "disagree on the number"),
        ({"inr": np.zeros((5, 4)), "outr": np.zeros((5, 7)), "t": np.arange(5.0)},
         r"variable 'outr': 7 output.*columns="),
        ({"inr": np.zeros((5, 4)), "outr": np.zeros((5, 10))}, "no time variable"),
        ({"inr": np.zeros((5, 4)), "outr": np.zeros((5, 10)), "t": np.r_[0, 1, 1, 2, 3.0]}, "field 'time'"),
    ],
)
def test_bad_plain_arrays(tmp_path, arrays, match):
    path = tmp_path / "bad.mat"
    scipy.io.savemat(path, arrays)
    with pytest.raises(FlightDataError, match=match):
        load_mat(path)


@pytest.mark.parametrize(
    ("cut", "match"),
    [
        (0, r"not a readable MATLAB v4/v5 file \(truncated, corrupt or v7.3\): MatReadError"),
        (100, "not a readable MATLAB"),
        (128, r"no variables in the file \(empty or truncated"),
        (40000, "not a readable MATLAB file: corrupt variable at byte 128: .*past the end of the file"),
    ],
)
def test_truncated_copies(shared_data, tmp_path, cut, match):
    path = tmp_path / "cut.mat"
    path.write_bytes((shared_data / "trex550" / "ppr_data.mat").read_bytes()[:cut])
    with pytest.raises(FlightDataError, match=r"cut\.mat: " + match):
        load(path)


def test_corrupt_compressed_block(tmp_path):
    path = tmp_path / "z.mat"
    scipy.io.savemat(path, {"inr": np.ones((50, 4)), "outr": np.ones((50, 10)), "t": np.arange(50.0)},
                     do_compression=True)
    data = bytearray(path.read_bytes())
    data[300:308] = bytes(8)
    path.write_bytes(bytes(data))
    with pytest.raises(FlightDataError, match=r"z\.mat: not a readable MATLAB.*(error|corrupt)"):
        load(path)
