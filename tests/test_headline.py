"""The diagnosis's first line: consistency findings first, then the effect with its size and shrink, then the base
model's shortfalls; where an unexplained, stick-driven gap lies instead of "no significant effect"; no parameter
lists."""

import dataclasses

import pytest

from jaxheli.gap.headline import NO_EFFECT, headline
from jaxheli.gap.localisation_record import LagPair, Summary
from jaxheli.gap.verdict import find

from test_verdict import _cases, _noise_first


def _where(coherent: bool = True, lagged: bool = True) -> Summary:
    """A localisation summary: q's worst band 0.5-2 Hz holds 64 % of its gap, coherent with the sticks or noise-like;
    q lagging lon by 40 ms, significant or not."""
    lag = LagPair("lon", "q", 0.04, 0.3, 0.1 if lagged else 0.5, lagged, ())
    return Summary("q", 0.12, (0.5, 2.0), 0.64, "structure" if coherent else "noise", (10.0, 20.0), 0.3, False, lag)


FINDINGS = (
    {"flight": "train", "kind": "rate_scale", "channels": ["p"], "estimate": 1.18, "significant": True},
    {"flight": "validate", "kind": "time_scale", "channels": ["time"], "estimate": 1.001, "significant": False},
    {"flight": "validate", "kind": "velocity_lag", "channels": ["w", "phi"], "estimate": -0.178, "significant": True},
    {"flight": "validate", "kind": "time_scale", "channels": ["time"], "estimate": 1.031, "significant": True},
    {"flight": "train", "kind": "attitude_bias", "channels": ["phi"], "estimate": 0.10, "significant": True},
)


def test_significant_defects_of_either_flight_come_first_and_the_effect_follows_in_words():
    """A significant finding the correction would apply leads; one that only asks for a look (a velocity lag) and
    an insignificant one stay out."""
    line = headline(find(*_cases()["under_fitted_then_effect"]), FINDINGS, _where())
    assert line == ("train flight data: rate scale x1.18 of p, attitude bias of phi; validate flight data: time scale "
                    "x1.03; lat input delay delay 80 +- 5 ms: the validation gap shrinks 40 %; the base model "
                    "under-fitted: re-fitted alone it shrinks the gap 12 %")


def test_the_effect_beyond_a_named_structure_leads_and_no_parameter_list_follows():
    line = headline(find(*_cases()["structure_then_effect"]), (), _where())
    assert line.startswith("lat input delay delay 80 +- 5 ms: the validation gap shrinks 22 % beyond the base "
                           "model's structure; the base model's structure: re-fitted in the physical ranges it "
                           "shrinks the gap 45 %")
    assert "Nw" not in line and "Xu" not in line
    assert "tied with actuator_lag" in headline(find(*_cases()["effect_tied"]), (), _where())


@pytest.mark.parametrize("coherent, lagged", [(True, True), (True, False), (False, True)])
def test_a_stick_driven_gap_no_effect_explains_is_located(coherent, lagged):
    line = headline(find(*_cases()["nothing"]), (), _where(coherent, lagged))
    assert line.startswith("no catalogued effect explains the base model's gap, which lies in q at 0.5-2 Hz "
                           "(64 % of its gap)")
    assert line.endswith(", q lagging lon by 40 ms") == lagged
    rest = headline(find(*_cases()["structure_only"]), (), _where(coherent, lagged))
    assert rest.startswith("the base model's structure: re-fitted in the physical ranges it shrinks the gap 45 %; "
                           "no catalogued effect explains the rest, which lies in q")


def test_a_noise_like_gap_with_nothing_found_is_no_significant_effect():
    assert headline(find(*_cases()["nothing"]), FINDINGS[1:3], _where(False, False)) == NO_EFFECT
    assert headline(find(*_cases()["nothing"]), FINDINGS[:1], _where(False, False)).endswith("; " + NO_EFFECT)


def test_a_base_still_converging_attributes_nothing():
    for name in ("unsettled", "unsettled_not_under"):
        line = headline(find(*_cases()[name]), (), _where())
        assert line == ("the base model is still converging (training RSS down 3.2 % over its last 60 steps): no "
                        "effect attributed"), name


def test_an_effect_named_in_place_of_process_noise_says_beyond_what_it_shrinks_the_gap():
    """Named beyond the noise, the effect's shrink is its shrink beyond the noise; a bias the noise adds nothing
    beyond is named with its own shrink."""
    ranking, beyond = _noise_first(True)
    line = headline(find(ranking, None, None, (), beyond), (), _where())
    assert line == "lat input delay delay 80 +- 5 ms: the validation gap shrinks 12 % beyond process noise"
    ranking, quiet = _noise_first(False)
    bias = dataclasses.replace(ranking[1], effect="output_bias_drift", shrink_pct=40.0)
    after = dataclasses.replace(ranking[0], shrink_pct=2.0, significant=False)
    line = headline(find([ranking[0], bias], None, None, (), quiet, {"output_bias_drift": after}), (), _where())
    assert line.endswith(": the validation gap shrinks 40 %")
