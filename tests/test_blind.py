"""Blind check: injections drawn as documented, scoring arithmetic, and a small blind run end to end."""

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from jaxheli._affinity import cores
from jaxheli.effects import plant as augmented
from jaxheli.effects import registry as fx
from jaxheli.gap import ledger
from jaxheli.benchmark.blind import (
    BOX, KINDS, NOISES, STRENGTHS, STYLES, TRUTHS, base_model, blind_flights, explainable,
    beyond_structure, explainable_beyond_structure, forms, markdown, resolvable,
    run_blind, sample_injection, scenario, summarise, summarise_bases, summarise_records, wilson_interval,
)
from jaxheli.benchmark.blind._pool import _process_on, _worker_cores
from jaxheli.benchmark.truth import outside_box
from jaxheli.cli import main
from jaxheli.gap.significance import MIN_SHRINK
from jaxheli.model import R50_SI, TABLE2
from jaxheli.synth.piloted import DEFAULT_OUTPUTS

LAY = augmented.layout(DEFAULT_OUTPUTS)


@pytest.fixture(autouse=True)
def _seed_ledger(tmp_path, monkeypatch):
    """Each test's seed ledger is a file of its own: the suite never writes the committed ledger, nor is refused by
    it."""
    monkeypatch.setenv(ledger.ENV, str(tmp_path / "seed_ledger.jsonl"))


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


def test_strength_scales_the_size_not_the_time_constant_and_stays_inside_the_box():
    weak, strong = sample_injection("rotor_speed_coupling", 5, strength=0.5), sample_injection(
        "rotor_speed_coupling", 5, strength=3.0)
    gain, tau = LAY["rotor"].start, LAY["rotor"].start + 1
    assert strong.eta[gain] == pytest.approx(6 * weak.eta[gain]) and strong.eta[tau] == weak.eta[tau]
    assert strong.value == strong.eta[gain]
    saturation = sample_injection("control_saturation", 5, strength=3.0)
    assert np.max(np.abs(saturation.eta[LAY["sat"]])) <= 0.8 * 100.0
    gusts = sample_injection("process_noise", 5, strength=2.0)
    assert gusts.gust == pytest.approx(2 * sample_injection("process_noise", 5).gust)


def test_scenarios_cover_every_combination_and_the_box_holds_every_truth():
    seen = {(w.truth, w.style, w.noise, w.strength) for w in map(scenario, range(96))}
    assert len(seen) == len(TRUTHS) * len(STYLES) * len(NOISES) * len(STRENGTHS) == 96
    lower, upper = BOX
    for seed in range(96):
        w = scenario(seed)
        reference = TABLE2 if w.truth.startswith("table2") else R50_SI
        ratio = np.divide(w.theta, reference, out=np.ones(40), where=reference != 0)
        assert np.all((0.7 <= ratio) & (ratio <= 1.3)) and np.all(w.theta[reference == 0] == 0)
        assert np.all((lower <= w.theta) & (w.theta <= upper)), seed
    np.testing.assert_array_equal(scenario(5).theta, scenario(5).theta)



def test_wide_scenarios_cover_their_combinations_with_truths_outside_the_authors_box():
    seen = {(w.truth, w.style, w.noise, w.strength) for w in (scenario(s, "wide") for s in range(48))}
    assert len(seen) == 48 and {t for t, *_ in seen} == {"table2+", "r50+"}
    for seed in range(10):
        w = scenario(seed, "wide")
        assert {"Nw", "Mu", "Mv", "Nv"} <= set(outside_box(w.theta)), seed
    np.testing.assert_array_equal(scenario(7, "wide").theta, scenario(7, "wide").theta)
    with pytest.raises(ValueError, match="unknown truth class"):
        scenario(0, "other")


RECORDS = [
    {"kind": "input_delay", "top": "input_delay", "correct": True, "in_tie": True, "magnitude_error": 0.1,
     "shrink_pct": 40.0, "oracle_shrink_pct": 50.0, "oracle_evidence_z": 3.0, "oracle_magnitude_error": 0.05,
     "magnitude_error_train": 0.2, "detectable": True, "resolvable": True},
    {"kind": "input_delay", "top": "actuator_lag", "correct": False, "in_tie": True, "magnitude_error": 0.3,
     "shrink_pct": 45.0, "oracle_shrink_pct": 50.0, "oracle_evidence_z": 0.4, "oracle_magnitude_error": 0.25,
     "magnitude_error_train": 0.4, "detectable": True, "resolvable": False},
    {"kind": "input_delay", "top": "none", "correct": False, "in_tie": False, "magnitude_error": 0.5,
     "shrink_pct": 1.0, "oracle_shrink_pct": 4.0, "oracle_evidence_z": 9.0, "oracle_magnitude_error": 0.6,
     "magnitude_error_train": 0.7, "detectable": False},
    {"kind": "none", "top": "none", "correct": True},
    {"kind": "none", "top": "none", "correct": True, "structure_named": True},
    {"kind": "none", "top": "process_noise", "correct": False},
]
"""Three delay trials (two detectable, one of them resolvable) and three controls, as a blind run records them."""


def test_summary_arithmetic_and_table():
    records = RECORDS
    s = summarise(records)
    row = s["kinds"]["input_delay"]
    assert row["top1_pct"] == pytest.approx(100 / 3) and row["in_tie_pct"] == pytest.approx(200 / 3)
    assert row["detectable_trials"] == 2 and row["top1_detectable_pct"] == 50.0  # the simulator found the third's effect below the noise
    assert row["in_tie_detectable_pct"] == 100.0
    assert row["magnitude_error_median_detectable"] == pytest.approx(0.2)
    assert row["magnitude_error_median_named"] == pytest.approx(0.1)  # the detectable trial named right alone
    assert row["shrink_vs_oracle_pct"] == pytest.approx(85.0)
    # the second trial's training flight does not show its effect (the simulator's verdict), nor resolve it (oracle
    # at 0.4 standard errors)
    assert row["resolvable_trials"] == 1 and row["top1_resolvable_pct"] == 100.0
    assert row["magnitude_error_median_resolvable"] == pytest.approx(0.1)
    assert not resolvable({**records[0], "detectable": False}) and not resolvable(records[1])
    assert row["identifiable_trials"] == 1 and row["top1_identifiable_pct"] == 100.0
    assert row["magnitude_error_median_identifiable"] == pytest.approx(0.1)
    assert row["oracle_magnitude_error_median_detectable"] == pytest.approx(0.15)
    assert row["oracle_magnitude_error_median_identifiable"] == pytest.approx(0.05)
    assert row["train_magnitude_error_median_detectable"] == pytest.approx(0.3)
    assert s["false_positive_pct"] == pytest.approx(100 / 3)
    assert (s["false_positives"], s["controls"]) == (1, 3)
    assert "(1 of 3; 95 % Wilson interval 6-79 %)" in markdown(s)
    assert s["kinds"]["none"]["structure_pct"] == pytest.approx(100 / 3) and row["structure_pct"] == 0.0
    # both detectable trials' oracles shrink the gap 50 % (>= MIN_SHRINK): the form could be credited in each
    assert row["explainable_trials"] == 2 and row["top1_explainable_pct"] == 50.0
    assert not explainable({**records[0], "oracle_shrink_pct": MIN_SHRINK - 0.1}) and not explainable(records[2])
    # no trial was ranked again beyond a structure: each explainable trial is explainable beyond it too
    assert row["explainable_beyond_structure_trials"] == 2 and row["top1_explainable_beyond_structure_pct"] == 50.0
    past = {**records[0], "oracle_beyond_structure_pct": MIN_SHRINK - 0.1}
    assert explainable(past) and not explainable_beyond_structure(past)
    assert explainable_beyond_structure({**past, "oracle_beyond_structure_pct": MIN_SHRINK})
    assert summarise([past, *records[1:]])["kinds"]["input_delay"]["explainable_beyond_structure_trials"] == 1
    assert ("| input_delay | 3 | 33 | 67 | 2 | 50 | 100 | 20.0 % | 10.0 % | 1 | 100 | 100 | 10.0 % | - | - | - | - "
            "| 1 | 100 | 100 | 10.0 % | 20.0 % | 5.0 % | 85.0 | 0 | 2 | 50 | 2 | 50 |") in markdown(s)
    # records without the structure's reach have no such subset
    assert "beyond_structure_trials" not in row and not beyond_structure(records[0])


def test_trials_beyond_the_structures_reach_are_the_resolvable_ones_a_hover_model_leaves_above_the_noise():
    reach = [2.0, 0.8, 3.0]  # the second trial is not resolvable (its training flight), whatever its reach
    records = [{**r, "structure_reach": v} for r, v in zip(RECORDS, reach)]
    row = summarise(records)["kinds"]["input_delay"]
    assert row["beyond_structure_trials"] == 1 and row["top1_beyond_structure_pct"] == 100.0
    assert beyond_structure(records[0]) and not beyond_structure({**records[0], "structure_reach": 1.0})
    within = summarise([{**records[0], "structure_reach": 0.9}, *records[1:]])["kinds"]["input_delay"]
    assert within["beyond_structure_trials"] == 0 and within["top1_beyond_structure_pct"] is None
    assert "| 1 | 100 | 100 | 10.0 % | 1 | 100 | 100 | 10.0 % |" in markdown(summarise(records))


def test_an_earlier_runs_records_are_summarised_again_without_running(tmp_path, capsys):
    path = tmp_path / "blind.json"
    path.write_text(json.dumps({"summary": {"settings": {"split": "test"}},
                                "records": [{**r, "base": {"method": "pem"}} for r in RECORDS]}))
    assert main(["blind", "--summarise", str(path), "--out", str(tmp_path / "again")]) == 0
    table = (tmp_path / "again" / "blind.md").read_text()
    assert "| 2 | 50 |" in table and "False positives on effect-free flights: 33 %" in table
    assert table.strip() in capsys.readouterr().out
    path.write_text("{}")
    with pytest.raises(ValueError, match="blind.json: not a blind run's records"):
        summarise_records(path)


def test_other_base_methods_are_summarised_beside_pem_on_the_same_trials():
    """PEM controls on seeds 0-2 (seed 2 a false positive) and IWO + polish ones on seeds 0-1 (seed 1 one): the main
    table is PEM's over every seed; IWO's is set beside PEM's over seeds 0-1 alone."""
    def control(seed, method, top="none"):
        return {"kind": "none", "seed": seed, "top": top, "correct": top == "none", "base": {"method": method}}

    records = [control(0, "pem"), control(1, "pem"), control(2, "pem", "input_delay"), control(0, "iwo+polish"),
               control(1, "iwo+polish", "quadratic_drag")]
    s = summarise_bases(records)
    assert s["false_positive_pct"] == pytest.approx(100 / 3) and s["kinds"]["none"]["trials"] == 3
    both = s["bases"]["iwo+polish"]
    assert both["iwo+polish"]["false_positive_pct"] == 50.0 and both["pem"]["false_positive_pct"] == 0.0
    assert both["pem"]["kinds"]["none"]["trials"] == 2
    text = markdown(s)
    assert "### Base model by iwo+polish against pem, on the same trials (seeds 0-1)" in text
    assert text.count("False positives on effect-free flights") == 3
    assert summarise_bases(records[:3])["bases"] == {}
    default = summarise_bases([{**r, "base": {"method": "iwo+freq+polish"}} for r in records[:3]])
    assert default["base"] == "iwo+freq+polish" and default["kinds"]["none"]["trials"] == 3


def test_the_independent_trials_are_pooled_by_form_in_family_and_other():
    def trial(kind, correct, resolvable=True, truth_sim="independent", oracle=10.0):
        return {"kind": kind, "correct": correct, "truth_sim": truth_sim, "detectable": True,
                "resolvable": resolvable, "oracle_shrink_pct": oracle}

    rows = [trial("drag", True), trial("servo_limits", False), trial("logger_delay", True, oracle=0.5),
            trial("bias_drift", False, resolvable=False), trial("two_at_once", True), trial("quantisation", False),
            trial("input_delay", False, truth_sim="library"), trial("none", True)]
    pooled = forms(rows)
    assert pooled["in-family"]["trials"] == 2 and pooled["in-family"]["top1_pct"] == 50.0
    other = pooled["other forms"]
    assert other["trials"] == 3 and other["top1_pct"] == pytest.approx(200 / 3)
    assert other["resolvable_trials"] == 2 and other["top1_resolvable_pct"] == 100.0
    # the oracle explains the two-at-once trial only (the logger delay's shrinks 0.5 %, under MIN_SHRINK)
    assert other["resolvable_explainable_trials"] == 1 and other["top1_resolvable_explainable_pct"] == 100.0
    assert pooled["in-family"]["resolvable_explainable_trials"] == 2
    assert f"shrinks the gap by {MIN_SHRINK:g} % or more on 1 of them, top-1 100 % there" in markdown(
        {"kinds": {}, "forms": pooled, "false_positive_pct": None})
    assert "beyond_structure_trials" not in other
    reached = forms([{**r, "structure_reach": 0.5 if r["kind"] == "logger_delay" else 2.0} for r in rows])
    other = reached["other forms"]
    assert other["beyond_structure_trials"] == 1 and other["top1_beyond_structure_pct"] == 100.0
    assert reached["in-family"]["beyond_structure_trials"] == 2


def test_trials_run_on_the_protocols_seeds_and_record_the_thresholds(tmp_path, monkeypatch):
    """Test seeds come from the thresholds file's protocol (controls twice as many by default); the settings record
    the split, the seeds and every threshold in force (an empty ledger: none spent yet)."""
    from jaxheli.benchmark import blind
    from jaxheli.gap.thresholds import THRESHOLDS

    seen = []

    def fake(trials, *, on_trial=None, workers=1, **options):
        seen.extend(trials)
        return [{"kind": t.kind, "seed": t.seed, "top": "none", "correct": t.kind == "none", "detectable": True,
                 "base": {"method": t.base}, "trial_base": t.base} for t in trials]

    monkeypatch.setattr(blind._run, "run_blind", fake)
    summary = blind.run_benchmark(["input_delay", "none"], 2, tmp_path, split="test", iwo_seeds=1, restart="segment",
                                  segment=6.0)
    first = THRESHOLDS.protocol.test_from
    assert sorted((t.kind, t.seed) for t in seen if t.base == "pem") == sorted(
        [("input_delay", first), ("input_delay", first + 1)] + [("none", first + i) for i in range(4)])
    assert sorted((t.kind, t.seed) for t in seen if t.base != "pem") == [("input_delay", first), ("none", first)]
    settings = summary["settings"]
    assert settings["split"] == "test" and settings["seed_range"] == [first, first + 3]
    assert settings["thresholds"]["min_shrink"] == THRESHOLDS.min_shrink and settings["thresholds"]["file"]
    assert settings["restart"] == "segment" and settings["segment"] == 6.0


def test_no_fit_starts_at_an_injected_value():
    """Over many draws of every kind, no injected effect parameter equals any start a candidate fit tries."""
    from jaxheli.effects.plant import no_effect

    *arrays, _ = fx.tried_arrays(fx.ALL, DEFAULT_OUTPUTS)
    index, start = arrays[0], arrays[1]
    pad = len(no_effect(DEFAULT_OUTPUTS))
    for kind in fx.ALL:
        for seed in range(40):
            inj = sample_injection(kind, seed, strength=(0.5, 1.0, 2.0, 3.0)[seed % 4])
            real = index < pad
            starts = start[real]
            injected = inj.eta[index[real]]
            moved = injected != no_effect(DEFAULT_OUTPUTS)[index[real]]
            assert not np.any(moved & (starts == injected)), (kind, seed)


def test_a_trial_without_a_constant_channel_keeps_every_other_effect_value():
    """A channel constant on a trial's flight (quantised coarser than it moves) is left out as a user would; the
    injection keeps each parameter that still exists, and loses its primary when that was the channel's own."""
    from jaxheli.benchmark.blind._injection import _restrict

    inj = sample_injection("output_bias_drift", 3)
    names = {p.name: p.slot for p in fx.params(inj.kind, DEFAULT_OUTPUTS)}
    fewer = tuple(c for c in DEFAULT_OUTPUTS if c != "w")
    cut = _restrict(inj, fewer)
    for p in fx.params(inj.kind, fewer):
        assert cut.eta[p.slot] == inj.eta[names[p.name]]
    assert len(cut.eta) == len(augmented.no_effect(fewer))
    assert (cut.primary, cut.value) == ((inj.primary, inj.value) if inj.primary in {p.name for p in
                                         fx.params(inj.kind, fewer)} else (None, 0.0))
    assert _restrict(sample_injection("none", 3), fewer).primary is None


def test_an_unknown_base_method_is_named():
    with pytest.raises(ValueError, match="unknown base method 'oracle'"):
        base_model(blind_flights(sample_injection("none", 0), 0, scenario(0), duration=12.0)[0], "oracle", 0)


def test_an_unknown_restart_or_box_is_named_before_any_flight():
    from jaxheli.benchmark.blind import run_trial
    with pytest.raises(ValueError, match="unknown restart 'smoothed'; restarts are"):
        run_trial("none", 0, restart="smoothed")
    with pytest.raises(ValueError, match="unknown box 'wide'"):
        run_trial("none", 0, box="wide")


@pytest.mark.parametrize("truth", ["independent", "library"])
def test_the_noise_free_pairs_are_the_flights_whose_detectability_the_trial_records(truth):
    """Either flight's noise-free pair (with the effect, re-flown without it) is the pair the blind trial scored:
    its ratio is the trial's detectability (validation) and training detectability, and the two flights differ."""
    from jaxheli.benchmark import truth as independent_truth
    from jaxheli.benchmark.blind import noise_free_pair
    from jaxheli.benchmark.blind._flights import _library_detectability, _library_seeds

    kind, seed, duration = "logger_delay" if truth == "independent" else "input_delay", 7, 12.0
    pairs = [noise_free_pair(truth, kind, seed, train=train, duration=duration) for train in (False, True)]
    ratios = [independent_truth.detectability_ratio(flown[2], bare[2], sigma) for flown, bare, sigma in pairs]
    where = scenario(seed)
    if truth == "independent":
        trial = independent_truth.truth_trial(kind, seed, where.theta, style=where.style, noise=where.noise,
                                              strength=where.strength, duration=duration)
        expected = [trial.score, trial.train_score]
    else:
        injection_seed, flight_seed = _library_seeds(kind, seed)
        inj = sample_injection(kind, injection_seed, DEFAULT_OUTPUTS, duration, where.strength)
        expected = [_library_detectability(inj, flight_seed, where, duration=duration, dt=0.05,
                                           outputs=DEFAULT_OUTPUTS, train=train) for train in (False, True)]
    np.testing.assert_allclose(ratios, expected, rtol=1e-12)
    assert min(ratios) > 0 and not np.allclose(pairs[0][0][1], pairs[1][0][1])


def test_validation_flight_differs_from_training_flight():
    where = scenario(1)
    train, validate = blind_flights(sample_injection("input_delay", 1), 1, where, duration=12.0)
    assert train.n_samples == validate.n_samples == 241
    assert not np.allclose(train.inputs, validate.inputs)
    assert train.metadata["effect"] == validate.metadata["effect"]


def test_small_blind_run_attributes_saturation():
    """Identified base (PEM on the contaminated flight), joint diagnosis: a lat saturation at 0.15 stick is
    named with its size, and stays named beyond the base model's structure (effect-free flights are cleared in
    ``tests/test_diagnose.py``: clean, under-fitted base, truth outside the box)."""
    (saturation,) = run_blind([("control_saturation", 72)], duration=20.0, max_steps=15, pem_steps=100)
    assert saturation["truth"] == "table2" and saturation["strength"] == 3.0 and saturation["base"]["method"] == "pem"
    assert saturation["top"] == "control_saturation" and saturation["correct"] and saturation["in_tie"]
    assert saturation["magnitude_error"] < 0.25 and saturation["oracle_shrink_pct"] > 10
    assert saturation["oracle_evidence_z"] >= 1.0
    assert saturation["resolvable"] == (saturation["detectable"] and saturation["detectability_train"] > 1.0)
    assert len(saturation["ranking"]) == 8 and saturation["box"] == "hull"
    assert all(e["effect"] == "control_saturation" for e in saturation["recheck"] if e["significant"])
    # the oracle is fitted beyond the structure exactly where the effects were ranked again there
    beyond = saturation["oracle_beyond_structure_pct"]
    assert (beyond is None) == (not saturation["recheck"]) and (beyond is None or np.isfinite(beyond))


def _exited(pid: int) -> bool:
    """``pid`` is gone or a zombie (ended, not yet reaped)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_trial_worker_outlives_no_run_that_spawned_it():
    """A worker watching its run (``_exit_with``) stays while the run lives and ends once it is gone."""
    worker = "import sys; from jaxheli.benchmark.blind._pool import _exit_with; _exit_with(int(sys.argv[1]), 0.1)"
    run = ("import os, subprocess, sys, time; "
           f"w = subprocess.Popen([sys.executable, '-c', {worker!r}, str(os.getpid())]); "
           "time.sleep(8); print(w.pid, w.poll() is None)")
    out = subprocess.run([sys.executable, "-c", run], capture_output=True, text=True, check=True, timeout=120)
    pid, alive = out.stdout.split()
    assert alive == "True"
    deadline = time.monotonic() + 30
    while not _exited(int(pid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _exited(int(pid))


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no sched_setaffinity on this platform")
def test_each_trial_process_starts_on_a_core_of_its_own():
    """Trial processes are started on their core (before they import JAX), the run's own thread gets its cores
    back, and more workers than cores are not pinned."""
    before = os.sched_getaffinity(0)
    try:
        try:
            os.sched_setaffinity(0, range(os.cpu_count() or 1))  # an xdist worker is pinned already: widen it
        except OSError:
            pass
        usable = cores()
        if len(usable) < 2:
            pytest.skip("one core")
        assert _worker_cores(len(usable)) == usable and _worker_cores(len(usable) + 1) == [None] * (len(usable) + 1)
        with _process_on(usable[-1]) as pool:
            assert pool.submit(os.sched_getaffinity, 0).result() == {usable[-1]}
            assert os.sched_getaffinity(0) == set(usable)
    finally:
        os.sched_setaffinity(0, before)


@pytest.mark.parametrize("k, n", [(0, 40), (1, 40), (6, 40), (20, 20), (3, 7)])
def test_false_positive_interval_is_the_wilson_score_interval(k, n):
    """The closed form (p + z^2/2n +- z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n), z the 97.5 % normal quantile."""
    z, p = 1.959963984540054, k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    assert wilson_interval(k, n) == pytest.approx((100 * (centre - half), 100 * (centre + half)), abs=1e-9)
