"""Several records in one fit: costs add (checked against numpy), each record its own initial state, and the
``FILE[:t0-t1]`` windows of the command line."""

import json

import numpy as np
import pytest

from jaxheli.cli import main
from jaxheli.data.preprocess import trim
from jaxheli.flights import load_flight, parse_spec
from jaxheli.io import load, save_npz
from jaxheli.model import TABLE2
from jaxheli.optim.output_error import output_error_problem
from jaxheli.optim.polish import polish
from jaxheli.problem import Records, make_problem, make_records, parts
from jaxheli.sim.shooting import run_states
from jaxheli.sim.simulate import simulate
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import piloted_flight

CHANNELS = ("u", "v", "p", "q", "phi", "theta", "w", "r")


@pytest.fixture(scope="module")
def flights():
    manoeuvres = Excitation("3211", unit=0.15)
    return [piloted_flight(TABLE2, duration=d, dt=0.02, excitation=manoeuvres, seed=s) for d, s in ((8.0, 5), (7.0, 6))]


def _numpy_costs(theta, flight):
    """The paper's cost and the summed normalised squared error of one record, in numpy (one run from rest)."""
    y = np.asarray(simulate(theta, flight, outputs=CHANNELS))
    m = flight.select(CHANNELS).outputs
    rho = np.array([np.corrcoef(y[:, i], m[:, i])[0, 1] for i in range(len(CHANNELS))])
    nmse = np.sum((y - m) ** 2, axis=0) / np.sum((m - m.mean(axis=0)) ** 2, axis=0)
    return np.sum((1 - rho) ** 2), np.sum(nmse), np.sum(((y - m) / m.std(axis=0)) ** 2)


@pytest.mark.parametrize("cost", ["pearson", "output-error"])
def test_records_cost_is_the_sum_of_the_single_record_costs(flights, cost):
    thetas = np.stack([TABLE2, TABLE2 * 1.1])
    records = make_records(flights, outputs=CHANNELS, cost=cost, precision="float64")
    got = np.asarray(records.population_cost()(thetas))
    index = 0 if cost == "pearson" else 1
    expected = [sum(_numpy_costs(th, f)[index] for f in flights) for th in thetas]
    np.testing.assert_allclose(got, expected, rtol=1e-8)


def test_least_squares_over_records_adds_the_sums_of_squares(flights):
    records = make_records(flights, outputs=CHANNELS)
    start = TABLE2 * 1.05
    res = polish(start, records, objective="pem", max_steps=1)  # one run from rest per record
    paper, _, rss = (sum(v) for v in zip(*(_numpy_costs(start, f) for f in flights)))
    np.testing.assert_allclose([res.cost_start, res.rss_start], [paper, rss], rtol=1e-8)


def test_each_record_gets_its_own_initial_state(flights):
    first = flights[0]
    moved = np.zeros(13)
    moved[1] = 0.4  # v = 0.4 m/s at the start of the second record
    offset = np.asarray(make_problem(first).sim.replace_x0(moved)(TABLE2)) - np.asarray(make_problem(first).sim(TABLE2))
    second = first.replace(outputs=np.asarray(first.outputs) + offset)
    chosen = output_error_problem(make_records([first, second]), TABLE2)
    assert isinstance(chosen, Records) and len(parts(chosen)) == 2
    x0 = [np.asarray(run_states(p.sim, TABLE2))[0] for p in parts(chosen)]
    assert abs(x0[0][1]) < 0.05 and abs(x0[1][1] - 0.4) < 0.05


def test_parse_spec_reads_windows(tmp_path):
    assert parse_spec("flight.mat") == ("flight.mat", None, None)
    assert parse_spec("flight.mat:10-25.5") == ("flight.mat", 10.0, 25.5)
    assert parse_spec("default:-30") == ("default", None, 30.0)
    assert parse_spec("a/b.csv:5-") == ("a/b.csv", 5.0, None)
    odd = tmp_path / "x:1-2"  # an existing file is taken whole
    odd.write_text("")
    assert parse_spec(str(odd)) == (str(odd), None, None)
    with pytest.raises(ValueError, match="after its start"):
        parse_spec("flight.mat:20-10")


def test_load_flight_cuts_the_window(flights, tmp_path):
    path = tmp_path / "f.npz"
    save_npz(flights[0], path)
    cut = load_flight(f"{path}:2-5")
    keep = (flights[0].time >= 2.0) & (flights[0].time <= 5.0)
    np.testing.assert_array_equal(cut.outputs, flights[0].outputs[keep])


def test_identify_cli_fits_several_windows(flights, tmp_path):
    path = tmp_path / "f.npz"
    save_npz(flights[0], path)
    out = tmp_path / "run"
    rc = main(["identify", "--method", "iwo+polish", "--train", f"{path}:0-4", f"{path}:4-8", "--iterations", "2",
               "--polish-steps", "3", "--polish-rounds", "1", "--out", str(out)])
    assert rc == 0
    content = json.loads((out / "result.json").read_text())
    assert content["settings"]["polish_rounds"] == 1 and len(content["polish"]["rounds"]) == 1
    assert content["polish"]["rounds"][0]["segment_s"] == [None, None]  # 4 s records: one run each
    for name in ("train_flight.npz", "train_flight_2.npz", "verification_train.png", "verification_train_2.png"):
        assert (out / name).is_file(), name
    assert load(out / "train_flight_2.npz").n_samples == trim(flights[0], 4.0, 8.0).n_samples


def test_records_of_flight_a_whole_record(shared_data):
    """Flight A's whole armed session in two airborne windows: the cost of both is the sum of each."""
    windows = [load_flight(f"{shared_data / 'trex550' / 'tested.mat'}:{w}") for w in ("50-60", "60-70")]
    chans = ("p", "q", "phi", "theta")
    records = make_records(windows, outputs=chans, precision="float64")
    got = float(records.population_cost()(TABLE2[None])[0])
    single = [float(make_problem(w, outputs=chans, precision="float64").population_cost()(TABLE2[None])[0])
              for w in windows]
    assert got == pytest.approx(sum(single), rel=1e-10)
