"""Model-structure determination (fix what the flight cannot determine, re-fit), the Gaussian prior of the local
fits, the named search boxes, and ``fixed`` in ``result.json``."""

import json

import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.bounds import Bounds, named_box
from jaxheli.data.flight import FlightData
from jaxheli.model import LOWER, N_PARAMS, PARAM_NAMES, TABLE2, UPPER, WIDE_LOWER, WIDE_UPPER
from jaxheli.cli.identify import print_fixed
from jaxheli.identify import identify
from jaxheli.optim.output_error import output_error, output_error_problem
from jaxheli.optim.pem import pem
from jaxheli.optim.prior import FLOOR_FRACTION, Prior
from jaxheli.optim.structure import determine_structure, fixed_value, select_fixed
from jaxheli.optim.uncertainty import from_residuals
from jaxheli.report import load_results
from jaxheli.report.sections import parameters
from jaxheli.results import save_result
from jaxheli.sim.simulate import simulate
from jaxheli.synth.excitation import multisine

OUTPUTS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
FREE = ("Xu", "Yv", "Lb", "Ma", "tf", "Nr", "Alon", "Blat", "Dlat", "Zcol", "Ncol", "Nped")
"""The parameters fitted in the flight tests (the rest pinned at the truth, Table 2): a small, fast problem."""
IDX = [PARAM_NAMES.index(n) for n in FREE]


def _box(free=FREE) -> Bounds:
    """Table 2 pinned, ``free`` in the authors' bounds."""
    lower, upper = TABLE2.copy(), TABLE2.copy()
    for n in free:
        i = PARAM_NAMES.index(n)
        lower[i], upper[i] = LOWER[i], UPPER[i]
    return Bounds(lower, upper)


def _flight(seed: int = 1, duration: float = 8.0, dt: float = 0.04, still: int | None = 2) -> FlightData:
    """Open-loop Table 2 response to random-phase multisines, the stick ``still`` held at 0 (never moves), plus
    1 % noise."""
    t = np.arange(0.0, duration + dt / 2, dt)
    freqs = 0.2 * np.arange(1, 33)
    sticks = np.stack([multisine(t, freqs[i::4], 0.05, phases="random", seed=10 * seed + i) for i in range(4)], 1)
    if still is not None:
        sticks[:, still] = 0.0
    clean = np.asarray(simulate(TABLE2, FlightData(t, sticks, np.tile(np.arange(8.0), (t.size, 1)), OUTPUTS)))
    rng = np.random.default_rng(seed)
    outputs = clean + 0.01 * clean.std(axis=0) * rng.standard_normal(clean.shape)
    return FlightData(t, sticks, outputs, OUTPUTS, source=f"synthetic flight {seed}, stick {still} still")


@pytest.fixture(scope="module")
def still_pedal():
    """A flight whose pedal never moves, identified by PEM from a 10 % perturbed start with the structure
    determined (the rest of the box pinned at the truth)."""
    flight = _flight()
    box = _box()
    start = TABLE2.copy()
    start[IDX] *= 1.0 + 0.1 * np.where(np.arange(len(IDX)) % 2, 1.0, -1.0)
    return flight, identify(flight, method="pem", lower=np.asarray(box.lower), upper=np.asarray(box.upper),
                            start=start, pem_segment=4.0, structure=True)


def test_a_stick_that_never_moves_fixes_its_parameter_and_the_rest_are_recovered(still_pedal):
    _, result = still_pedal
    assert list(result.fixed) == ["Nped"]
    nped = result.fixed["Nped"]
    assert nped["value"] == 0.0 and nped["source"] == "zero" and nped["relative_se"] == "inf"
    assert "unresolved" in nped["reason"] and nped["round"] == 1
    i = PARAM_NAMES.index("Nped")
    assert result.params[i] == 0.0 and result.stderr["Nped"] == 0.0  # held, no longer estimated
    kept = [i for i, n in zip(IDX, FREE) if n != "Nped"]
    np.testing.assert_allclose(result.params[kept], TABLE2[kept], rtol=0.02)
    assert all(0 < result.stderr[n] < 0.05 * abs(TABLE2[PARAM_NAMES.index(n)]) for n in FREE if n != "Nped")
    # the pedal's term had no effect on the record: holding it at 0 costs nothing
    structure = result.structure
    assert structure["rss"] <= 1.01 * structure["rss_start"] and len(structure["rounds"]) == 1
    assert result.settings["structure"] and result.settings["prior"] is None


def test_result_json_round_trips_fixed(still_pedal, tmp_path):
    flight, result = still_pedal
    save_result(result, tmp_path, flight)
    content = json.loads((tmp_path / "result.json").read_text())
    assert content["fixed"] == json.loads(json.dumps(result.fixed))
    assert content["structure"]["rounds"][0]["fixed"] == ["Nped"]
    assert "Nped" not in {a["name"] for a in content["at_bounds"]}
    body = parameters(load_results([tmp_path]))
    assert "<caption>fixed parameters</caption>" in body and "<caption>parameters at bounds</caption>" in body
    assert '<td class="text">Nped</td><td class="text">zero</td>' in body
    assert f"{0.0:.4g} (fixed)" in body


def test_structure_needs_a_least_squares_fit():
    with pytest.raises(ValueError, match="method 'iwo' does not use 'structure'"):
        identify(_flight(duration=1.0), method="iwo", structure=True, iterations=1)
    with pytest.raises(ValueError, match="needs a least-squares fit to repeat"):
        identify(_flight(duration=1.0), method="iwo+polish", structure=True, polish_objective="pearson")


def test_the_console_prints_one_line_per_fixed_parameter(still_pedal, capsys):
    _, result = still_pedal
    print_fixed(result.fixed, result.structure)
    print_fixed(None, None)
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("fixed parameters (model-structure determination): 1; sum of squares")
    assert lines[0].endswith("1 of 1 re-fits accepted")
    assert lines[1].startswith("  Nped = 0 (zero, round 1): unresolved")
    assert lines[2] == "fixed parameters (model-structure determination): not run (--structure)"


def test_nothing_is_fixed_when_every_stick_moves():
    flight = _flight(still=None)
    box = _box(FREE[:-1] + ("Nped",))
    found = determine_structure(flight, TABLE2, segment=4.0, lower=box.lower, upper=box.upper, max_steps=30)
    assert found.fixed == () and found.rounds == ()
    np.testing.assert_array_equal(found.theta, TABLE2)


def test_output_error_judges_every_try_on_the_free_fits_runs(monkeypatch):
    """Output error shortens the runs of an unstable model, so a re-fit judged on its own runs could lower its sum
    of squares by turning unstable: every sum the test compares is over the runs the free fit chooses."""
    import jaxheli.optim.structure as structure

    chosen_at = []

    def spy(problem, theta, *args, **kwargs):
        chosen_at.append(np.asarray(theta).copy())
        return output_error_problem(problem, theta, *args, **kwargs)

    monkeypatch.setattr(structure, "output_error_problem", spy)
    box = _box()
    start = TABLE2.copy()
    start[PARAM_NAMES.index("Lb")] *= 1.01
    found = determine_structure(_flight(), start, local_fit="output-error", lower=box.lower, upper=box.upper,
                                max_steps=5, rounds=1)
    assert found.rounds and not np.array_equal(found.theta, start)
    assert len(chosen_at) == 1 + len(found.rounds) and all(np.array_equal(t, start) for t in chosen_at)


def test_output_error_refits_from_the_optimum_in_one_round_without_the_ladder(monkeypatch):
    """The polish's re-fit (output error) starts at an optimum: one round at the runs that point chooses, not the
    ladder of 5-s and 20-s runs a population optimiser's start needs; the still pedal is fixed as with PEM."""
    import jaxheli.optim.structure as structure

    refits = []

    def spy(*args, **kwargs):
        res = output_error(*args, **kwargs)
        refits.append(res.settings["rounds"])
        return res

    monkeypatch.setattr(structure, "output_error", spy)
    box = _box()
    found = determine_structure(_flight(), TABLE2, local_fit="output-error", lower=box.lower, upper=box.upper,
                                max_steps=20)
    assert [f.name for f in found.fixed] == ["Nped"] and refits
    assert all(len(history) == 1 and not history[0]["ladder"] for history in refits)


def test_a_fix_that_raises_the_sum_of_squares_is_refused():
    """With every parameter a candidate (a tiny threshold), the round's test refuses fixing the determined ones and
    keeps the unresolved one's fix alone."""
    flight = _flight(duration=4.0)
    box = _box(("Lb", "Ma", "Nped"))
    found = determine_structure(flight, TABLE2, segment=4.0, lower=box.lower, upper=box.upper, max_steps=20,
                                max_relative_se=1e-9, max_rounds=1)
    tries = [(t["fixed"], t["accepted"]) for t in found.rounds]
    # fixing all three would leave nothing free: not tried; Nped with the worse of Lb, Ma refused, Nped alone kept
    assert len(tries) == 2 and tries[0][0][0] == "Nped" and len(tries[0][0]) == 2 and tries[0][1] is False
    assert tries[1] == (["Nped"], True)
    assert [f.name for f in found.fixed] == ["Nped"]
    refused = found.rounds[0]
    assert refused["rise_sigma2"] > refused["limit"] > 0
    np.testing.assert_allclose(found.theta[[PARAM_NAMES.index("Lb"), PARAM_NAMES.index("Ma")]],
                               TABLE2[[PARAM_NAMES.index("Lb"), PARAM_NAMES.index("Ma")]], rtol=0.01)


def _linear_uncertainty(rho_target: float, scales: tuple[float, ...]):
    """Standard errors of a linear least-squares problem in three of the 40 parameters, two of whose regressors
    have correlation close to ``rho_target``; returns the uncertainty and the numpy covariance."""
    rng = np.random.default_rng(0)
    m = 400
    a = rng.standard_normal(m)
    b = rho_target * a + np.sqrt(1 - rho_target**2) * rng.standard_normal(m)
    X = np.stack([a, b, rng.standard_normal(m)], 1) * np.array(scales)
    idx = [PARAM_NAMES.index(n) for n in ("Xu", "Yv", "Lb")]
    truth = np.array([-0.3, -0.9, 130.0])
    y = X @ truth + 0.5 * rng.standard_normal(m)
    box = Bounds(*(np.where(np.isin(np.arange(N_PARAMS), idx), v, TABLE2) for v in (WIDE_LOWER, WIDE_UPPER)))
    theta_hat = np.linalg.lstsq(X, y, rcond=None)[0]
    theta = TABLE2.copy()
    theta[idx] = theta_hat
    unc = from_residuals(lambda th: jnp.asarray(X) @ th[jnp.asarray(idx)] - jnp.asarray(y), theta, bounds=box)
    resid = X @ theta_hat - y
    cov = resid @ resid / (m - 3) * np.linalg.inv(X.T @ X)
    return unc, cov, idx, theta_hat


def test_the_correlation_rule_fixes_the_pair_member_with_the_larger_relative_error():
    unc, cov, idx, theta_hat = _linear_uncertainty(0.99, (1.0, 0.2, 1.0))
    corr = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    rel = np.sqrt(np.diag(cov)) / np.abs(theta_hat)
    np.testing.assert_allclose(unc.correlation[np.ix_(idx, idx)], corr, rtol=1e-6, atol=1e-9)
    assert abs(corr[0, 1]) > 0.95
    worse = idx[int(np.argmax(rel[:2]))]
    chosen = select_fixed(unc, max_relative_se=10.0)  # the correlation rule alone
    assert [c.index for c in chosen] == [worse]
    assert chosen[0].partner == PARAM_NAMES[idx[1 - int(np.argmax(rel[:2]))]]
    assert chosen[0].rho == pytest.approx(corr[0, 1], rel=1e-6)
    assert "correlated with" in chosen[0].reason
    # below the correlation threshold nothing is fixed
    assert select_fixed(unc, max_relative_se=10.0, max_correlation=0.999) == []


def test_an_exactly_collinear_pair_fixes_one_of_the_two():
    rng = np.random.default_rng(1)
    a, c = rng.standard_normal(200), rng.standard_normal(200)
    X = np.stack([a, 2.0 * a, c], 1)  # Xu and Yv enter only as Xu + 2 Yv
    idx = jnp.asarray([PARAM_NAMES.index(n) for n in ("Xu", "Yv", "Lb")])
    free = np.isin(np.arange(N_PARAMS), np.asarray(idx))
    box = Bounds(*(np.where(free, v, TABLE2) for v in (WIDE_LOWER, WIDE_UPPER)))
    y = X @ np.array([-0.3, -0.9, 130.0]) + 0.1 * rng.standard_normal(200)
    unc = from_residuals(lambda th: jnp.asarray(X) @ th[idx] - jnp.asarray(y), TABLE2, bounds=box)
    chosen = select_fixed(unc)
    assert len([c for c in chosen if "unresolved" in c.reason]) == 1
    assert PARAM_NAMES[chosen[0].index] in ("Xu", "Yv")


def test_fixed_values_prior_zero_or_nearest_bound():
    box = Bounds()
    lb, xu = PARAM_NAMES.index("Lb"), PARAM_NAMES.index("Xu")
    assert fixed_value(xu, box) == (0.0, "zero")
    assert fixed_value(lb, box) == (120.0, "bound")  # 0 is outside [120, 220]
    prior = Prior.from_percent(TABLE2, 20.0)
    assert fixed_value(xu, box, prior) == (pytest.approx(TABLE2[xu]), "prior")
    far = Prior.from_percent(np.where(np.arange(N_PARAMS) == lb, 500.0, TABLE2), 20.0)
    assert fixed_value(lb, box, far) == (220.0, "prior")


def test_the_prior_residual_is_the_hand_computation():
    mean = TABLE2.copy()
    theta = TABLE2 + 0.1
    prior = Prior.from_percent(mean, 25.0)
    floor = FLOOR_FRACTION * (WIDE_UPPER - WIDE_LOWER)
    by_hand = [(theta[i] - mean[i]) / (0.25 * max(abs(mean[i]), floor[i])) for i in range(N_PARAMS)]
    np.testing.assert_allclose(np.asarray(prior.residuals(theta)), by_hand, rtol=1e-12)
    lw = PARAM_NAMES.index("Lw")  # prior 0: the floor sets the scale
    assert float(prior.sd[lw]) == pytest.approx(0.25 * FLOOR_FRACTION * 4.0)
    np.testing.assert_allclose(np.asarray(prior.residuals(theta, np.array([0, 6]))), [by_hand[0], by_hand[6]])
    with pytest.raises(ValueError):
        Prior.from_percent(mean, 0.0)


def test_a_tight_prior_holds_the_fit_at_the_prior():
    flight = _flight(duration=4.0, still=None)
    box = _box(("Xu", "Lb"))
    start = TABLE2.copy()
    start[PARAM_NAMES.index("Lb")] = 150.0
    away = np.where(np.arange(N_PARAMS) == PARAM_NAMES.index("Lb"), 180.0, TABLE2)
    settings = {"segment": 4.0, "lower": box.lower, "upper": box.upper, "start": start, "max_steps": 30}
    free = pem(flight, **settings)
    held = pem(flight, prior=Prior.from_percent(away, 0.01), **settings)
    lb = PARAM_NAMES.index("Lb")
    assert abs(free.theta[lb] - TABLE2[lb]) < 2.0
    assert abs(held.theta[lb] - 180.0) < 0.5
    assert held.settings["prior"] and not free.settings["prior"]


def test_the_wide_box_is_the_physical_ranges():
    wide = named_box("wide")
    np.testing.assert_array_equal(np.asarray(wide.lower), np.minimum(WIDE_LOWER, LOWER))
    np.testing.assert_array_equal(np.asarray(wide.upper), np.maximum(WIDE_UPPER, UPPER))
    assert bool(np.all(np.asarray(wide.free)))  # no parameter pinned
    authors = named_box("authors")
    np.testing.assert_array_equal(np.asarray(authors.lower), LOWER)
    with pytest.raises(ValueError):
        named_box("narrow")


class _Stop(Exception):
    """Raised by the stand-in for identify once it has seen its arguments."""


def test_the_command_line_passes_the_box_the_structure_and_the_prior(monkeypatch, tmp_path):
    import importlib

    from jaxheli.cli import main
    from jaxheli.io import save_npz

    seen = {}

    def fake(train, **options):
        seen.update(options)
        raise _Stop

    monkeypatch.setattr(importlib.import_module("jaxheli.identify"), "identify", fake)  # the module, not the function
    data = save_npz(_flight(duration=1.0), tmp_path / "flight.npz")
    args = ["identify", "--data", str(data), "--method", "pem", "--out", str(tmp_path / "out")]
    with pytest.raises(_Stop):
        main(args + ["--box", "wide", "--structure", "--prior", "table2", "--prior-sd", "20"])
    np.testing.assert_array_equal(seen["lower"], np.minimum(WIDE_LOWER, LOWER))
    np.testing.assert_array_equal(seen["upper"], np.maximum(WIDE_UPPER, UPPER))
    assert seen["structure"] is True and seen["prior"] == "table2" and seen["prior_sd"] == 20.0
    seen.clear()
    with pytest.raises(_Stop):
        main(args)
    np.testing.assert_array_equal(seen["lower"], LOWER)
    np.testing.assert_array_equal(seen["upper"], UPPER)
    assert not {"structure", "prior", "prior_sd"} & set(seen)  # options not given are not passed
