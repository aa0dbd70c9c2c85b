"""Modes of the hover model (jaxheli.modes) and parameters on a bound of the box (jaxheli.at_bounds)."""

import math

import numpy as np
import pytest

from jaxheli import LOWER, TABLE2, UPPER, build_ab
from jaxheli.at_bounds import at_bounds
from jaxheli.model import PARAM_NAMES
from jaxheli.modes import fastest_doubling, modes, modes_of

P = {n: i for i, n in enumerate(PARAM_NAMES)}


def test_eigenvalues_are_those_of_a():
    found = modes(TABLE2)
    expected = np.linalg.eigvals(np.asarray(build_ab(TABLE2)[0]))
    listed = [m.eigenvalue for m in found] + [m.eigenvalue.conjugate() for m in found if m.oscillatory]
    np.testing.assert_allclose(np.sort_complex(np.array(listed)), np.sort_complex(expected), rtol=1e-10, atol=1e-12)
    assert [m.eigenvalue.real for m in found] == sorted((m.eigenvalue.real for m in found), reverse=True)
    for m in found:
        np.testing.assert_allclose(m.participation.sum(), 1.0)


def test_table2_heave_root_and_yaw_block_by_hand():
    """With Lw = Mw = Nw = 0 (pinned) w feeds nothing: its root is Zw. (r, r_fb) feed only w, so their roots
    are those of [[Nr, Nrfb], [Kr, Krfb]]."""
    found = modes(TABLE2)
    heave = found[0]
    assert heave.eigenvalue == pytest.approx(TABLE2[P["Zw"]]) and heave.name == "yaw-heave (heave)"
    assert heave.states == ("w",) and heave.time_to_double == pytest.approx(math.log(2) / TABLE2[P["Zw"]])
    assert heave.time_to_half is None and heave.damping == pytest.approx(-1.0)
    nr, nrfb, kr, krfb = (TABLE2[P[n]] for n in ("Nr", "Nrfb", "Kr", "Krfb"))
    tr, det = nr + krfb, nr * krfb - nrfb * kr
    roots = sorted([(tr + s * math.sqrt(tr**2 - 4 * det)) / 2 for s in (1, -1)], reverse=True)
    yaw = [m for m in found if m.name.startswith("yaw-heave (yaw)")]
    assert [m.eigenvalue.real for m in yaw] == pytest.approx(roots)
    assert all(set(m.states) == {"r", "r_fb"} for m in yaw)
    assert fastest_doubling(found) is heave and heave.seen_in(("w",)) and not heave.seen_in(("u", "p", "r"))
    assert fastest_doubling(found, ("u", "v", "p", "q", "phi", "theta", "r")) is None  # w feeds none of them


def test_oscillatory_yaw_pair_frequency_damping_and_time_to_half():
    theta = TABLE2.copy()
    theta[[P["Nr"], P["Nrfb"], P["Kr"], P["Krfb"]]] = (-1.0, -4.0, 1.0, -1.0)  # roots -1 +- 2j
    pair = next(m for m in modes(theta) if m.eigenvalue == pytest.approx(complex(-1, 2)))
    assert pair.oscillatory and pair.name == "yaw-heave (yaw)"
    assert pair.natural_frequency == pytest.approx(math.sqrt(5)) and pair.damping == pytest.approx(1 / math.sqrt(5))
    assert pair.time_to_half == pytest.approx(math.log(2)) and pair.time_to_double is None
    assert "-1 +- 2j" in pair.describe() and "halves in 0.693 s" in pair.describe()


def test_participation_does_not_depend_on_the_states_units():
    A = np.asarray(build_ab(TABLE2)[0])
    D = np.diag([1 / 0.3048, 1 / 0.3048, 57.3, 57.3, 57.3, 57.3, 57.3, 57.3, 1 / 0.3048, 57.3, 10.0, 57.3, 57.3])
    for m, scaled in zip(modes_of(A), modes_of(D @ A @ np.linalg.inv(D))):
        assert m.name == scaled.name and m.states == scaled.states
        np.testing.assert_allclose(m.participation, scaled.participation, atol=1e-9)


def test_modes_json_names_units():
    content = modes(TABLE2)[0].to_json()
    assert content["eigenvalue"] == [pytest.approx(TABLE2[P["Zw"]]), 0.0]
    assert content["time_to_double_s"] == pytest.approx(15.16, abs=0.01) and content["time_to_half_s"] is None


def test_parameters_within_a_tenth_of_a_percent_of_a_bound_are_listed():
    theta = (LOWER + UPPER) / 2
    width = UPPER - LOWER
    theta[P["Mu"]] = UPPER[P["Mu"]]
    theta[P["Xu"]] = LOWER[P["Xu"]] + 0.0009 * width[P["Xu"]]
    theta[P["Xa"]] = LOWER[P["Xa"]] + 0.0011 * width[P["Xa"]]  # just outside
    found = at_bounds(theta)
    assert [(a.name, a.side, a.bound) for a in found] == [("Xu", "lower", -1.0), ("Mu", "upper", 0.1)]
    assert found[1].to_json() == {"name": "Mu", "value": 0.1, "side": "upper", "bound": 0.1}
    assert at_bounds((LOWER + UPPER) / 2) == ()  # pinned axes (lower == upper) are never listed
    assert [(a.name, a.side) for a in at_bounds(TABLE2)] == [("Mu", "upper"), ("Alat", "lower")]  # 0.1, -0.09993
