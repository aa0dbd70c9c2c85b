"""The base model's structure as the diagnosis's first hypothesis: the box widened to the physical ranges, pinned
parameters freed, credited like a candidate and named in the verdict before any effect (the whole diagnosis of a truth outside the
authors' box: ``tests/test_diagnose.py``)."""

import numpy as np

from jaxheli.bounds import Bounds
from jaxheli.gap.records import Structure
from jaxheli.gap.structure import physical_box
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
