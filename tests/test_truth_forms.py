"""Every kind of the independent truth simulator outside :data:`~jaxheli.benchmark.truth.IN_FAMILY` lies outside
its candidates' family: the nearest candidate, fitted alone with the truth's own hover model to the kind's noise-free
effect under the diagnosis's predictor, leaves a residual above the sensor noise. A candidate or truth change that
lets a candidate swallow a kind fails here (that kind then moves to ``IN_FAMILY``). Controls in a candidate's own
form stay within the noise, so the fit is not what keeps the residual up."""

import pytest

from jaxheli.benchmark import truth as ts
from jaxheli.benchmark.forms import form_gap, in_family, kind_gap
from jaxheli.model import TABLE2

DURATION, STRENGTH, STYLE = 15.0, 2.0, "validate"
"""Flights of 15 s with the held-out 3-2-1-1, effects at twice their size: every draw below is clearly detectable."""

OTHER_FORMS: dict[str, int] = {"logger_delay": 0, "servo_dynamics": 1, "dryden": 0, "imu_misalignment": 0,
                               "bias_drift": 0, "rotor_droop": 1}
"""The kinds outside every family, each with a draw (seed) whose effect is several noise std in size."""


def test_the_other_forms_are_every_single_kind_but_the_in_family_ones():
    assert set(OTHER_FORMS) | set(ts.IN_FAMILY) == set(ts.SINGLE)
    assert not set(OTHER_FORMS) & set(ts.IN_FAMILY)


@pytest.mark.parametrize("kind", sorted(OTHER_FORMS))
def test_no_candidate_reproduces_a_kind_in_a_form_of_its_own(kind):
    gap = kind_gap(kind, OTHER_FORMS[kind], TABLE2, style=STYLE, strength=STRENGTH, duration=DURATION)
    assert gap.size > 2.0, gap
    assert gap.residual > 1.0, f"{kind}: its nearest candidate {gap.nearest} reproduces it within the noise: {gap}"


@pytest.mark.parametrize("control", ["whole_frame_delay", "yaw_misalignment"])
def test_a_candidates_own_form_is_reproduced_within_the_noise(control):
    effects, candidates = in_family(0.05)[control]
    gap = form_gap(TABLE2, effects, candidates, style=STYLE, seed=0, duration=DURATION)
    assert gap.size > 2.0 and gap.residual < 0.5, gap
