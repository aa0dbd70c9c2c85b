"""The base model's structure as the diagnosis's first hypothesis: the box widened to the physical ranges, pinned
parameters freed, credited like a candidate and named in the verdict before any effect (the whole diagnosis of a truth outside the
authors' box: ``tests/test_diagnose.py``)."""

import numpy as np

from jaxheli.bounds import Bounds
from jaxheli.gap.records import Structure
from jaxheli.gap.structure import held_box, moved, physical_box
from jaxheli.model import LOWER, PARAM_NAMES, PINNED, UPPER, WIDE_LOWER, WIDE_UPPER


def test_physical_box_frees_the_pinned_parameters_and_keeps_a_wider_box():
    wide = physical_box(Bounds())
    lower, upper = np.asarray(wide.lower), np.asarray(wide.upper)
    assert np.all(lower <= LOWER) and np.all(upper >= UPPER)
    assert np.all(lower <= WIDE_LOWER) and np.all(upper >= WIDE_UPPER)
    assert all(upper[PARAM_NAMES.index(n)] > lower[PARAM_NAMES.index(n)] for n in PINNED)
    assert physical_box(Bounds(WIDE_LOWER, WIDE_UPPER)) is None
    wider = Bounds(WIDE_LOWER - 1.0, WIDE_UPPER + 1.0)
    assert physical_box(wider) is None  # already holds them: nothing to widen


def test_structure_summary_names_what_left_the_box():
    s = Structure(12.0, 3.0, True, 0.1, 0.088, {"r": 0.05}, {"Nw": 2.71}, {"Mu": -0.18}, {"Mu": -0.1},
                  np.zeros(40), {})
    assert s.summary == "Nw freed (2.71), Mu beyond its bound (-0.18 past -0.1)"
    assert Structure.from_json(s.to_json()).summary == s.summary
    held = Structure(30.0, 9.0, True, 0.1, 0.07, {"u": 0.05}, {"Nw": 2.0}, {}, {}, np.zeros(40), {}, ("Xu", "Yv"))
    assert held.summary == "Nw freed (2); Xu, Yv held in the box (they ran to the end of their physical range)"
    old = {k: v for k, v in s.to_json().items() if k != "at_limit"}  # a file written before the field was
    assert Structure.from_json(old).at_limit == () and Structure.from_json(held.to_json()).at_limit == ("Xu", "Yv")


def test_a_parameter_at_the_end_of_its_physical_range_is_held_in_the_box():
    """Of the parameters a widened re-fit moved out of the authors' box, those at the end of the physical range (to
    a thousandth of it) are at their limit, one short of it is not; the box the hypothesis is re-fitted in then keeps
    them within the authors' bounds (a pinned one pinned) and leaves every other parameter its physical range."""
    box, wide = Bounds(), physical_box(Bounds())
    i = {n: PARAM_NAMES.index(n) for n in ("Xu", "Yv", "Nw")}
    middle = 0.5 * (np.asarray(LOWER) + np.asarray(UPPER))
    theta = middle.copy()
    theta[i["Xu"]] = WIDE_LOWER[i["Xu"]]  # beyond its bound, at the physical limit
    theta[i["Yv"]] = WIDE_LOWER[i["Yv"]] + 0.01 * (WIDE_UPPER - WIDE_LOWER)[i["Yv"]]  # beyond, short of the limit
    theta[i["Nw"]] = 3.96  # freed
    freed, beyond, crossed, limit = moved(theta, box, wide)
    assert set(freed) == {"Nw"} and set(beyond) == {"Xu", "Yv"} and limit == ("Xu",)
    assert crossed["Xu"] == LOWER[i["Xu"]]
    theta[i["Nw"]] = WIDE_UPPER[i["Nw"]]
    assert moved(theta, box, wide)[3] == ("Xu", "Nw")
    assert moved(middle, box, wide) == ({}, {}, {}, ())
    kept = held_box(box, wide, ("Xu", "Nw"))
    for name, j in i.items():
        source = box if name in ("Xu", "Nw") else wide
        assert (kept.lower[j], kept.upper[j]) == (source.lower[j], source.upper[j]), name
    assert kept.lower[i["Nw"]] == kept.upper[i["Nw"]] == 0.0
