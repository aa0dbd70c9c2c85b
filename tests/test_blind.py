"""Blind check: injections drawn as documented, scoring arithmetic, and a small blind run end to end."""

import numpy as np
import pytest

from jaxheli.effects import plant as augmented
from jaxheli.gap.blind import KINDS, blind_flights, markdown, run_blind, sample_injection, summarise
from jaxheli.synth.piloted import DEFAULT_OUTPUTS

LAY = augmented.layout(DEFAULT_OUTPUTS)


@pytest.mark.parametrize("kind", KINDS)
def test_injections_are_reproducible_single_effects_in_range(kind):
    a, b = sample_injection(kind, 5), sample_injection(kind, 5)
    np.testing.assert_array_equal(a.eta, b.eta)
    changed = np.flatnonzero(a.eta != augmented.no_effect(DEFAULT_OUTPUTS))
    groups = {g for g, sl in LAY.items() for i in changed if sl.start <= i < sl.stop}
    expected = {"input_delay": {"delay"}, "actuator_lag": {"lag"}, "control_saturation": {"sat"},
                "output_bias_drift": {"bias", "drift"}, "process_noise": {"gust"}, "quadratic_drag": {"drag"},
                "rotor_speed_coupling": {"rotor"}, "sensor_misalignment": {"mis"}, "none": set()}[kind]
    assert groups == expected
    ranges = {"input_delay": (0.04, 0.12), "actuator_lag": (0.05, 0.15), "control_saturation": (0.3**-2, 0.15**-2),
              "process_noise": (0.3, 0.8), "quadratic_drag": (1.0, 3.0), "rotor_speed_coupling": (2.0, 5.0),
              "sensor_misalignment": (np.deg2rad(2), np.deg2rad(5))}
    if kind in ranges:
        lo, hi = ranges[kind]
        assert lo <= abs(a.value) <= hi
    assert (a.gust > 0) == (kind == "process_noise")
    assert not np.array_equal(sample_injection(kind, 6).eta, a.eta) or kind == "none"


def test_summary_arithmetic_and_table():
    records = [
        {"kind": "input_delay", "top": "input_delay", "correct": True, "magnitude_error": 0.1, "shrink_pct": 40.0,
         "oracle_shrink_pct": 50.0},
        {"kind": "input_delay", "top": "actuator_lag", "correct": False, "magnitude_error": 0.3, "shrink_pct": 45.0,
         "oracle_shrink_pct": 50.0},
        {"kind": "input_delay", "top": "none", "correct": False, "magnitude_error": 0.5, "shrink_pct": 1.0,
         "oracle_shrink_pct": 4.0},
        {"kind": "none", "top": "none", "correct": True},
        {"kind": "none", "top": "none", "correct": True},
        {"kind": "none", "top": "process_noise", "correct": False},
    ]
    s = summarise(records)
    row = s["kinds"]["input_delay"]
    assert row["top1_pct"] == pytest.approx(100 / 3) and row["magnitude_error_median"] == pytest.approx(0.3)
    assert row["shrink_vs_oracle_pct"] == pytest.approx(80.0)
    assert row["detectable_trials"] == 2 and row["top1_detectable_pct"] == 50.0  # the 4 % trial is below 10 %
    assert s["false_positive_pct"] == pytest.approx(100 / 3)
    assert "| input_delay | 3 | 33 | 2, 50 | 30.0 % | 80.0 |" in markdown(s)


def test_validation_flight_differs_from_training_flight():
    train, validate = blind_flights(sample_injection("input_delay", 1), 1, duration=12.0)
    assert train.n_samples == validate.n_samples == 241
    assert not np.allclose(train.inputs, validate.inputs)
    assert train.metadata["effect"] == validate.metadata["effect"]


def test_small_blind_run_attributes_delay_and_clears_control():
    records = run_blind([("input_delay", 0), ("none", 0)], duration=20.0, max_steps=15, batch=2)
    delay, control = records
    assert delay["top"] == "input_delay" and delay["correct"]
    assert delay["magnitude_error"] < 0.15
    assert delay["shrink_pct"] > 0.8 * delay["oracle_shrink_pct"]
    assert control["top"] == "none" and control["correct"]
    assert all(len(r["ranking"]) == 8 for r in records)
