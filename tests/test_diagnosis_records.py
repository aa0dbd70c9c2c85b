"""The diagnosis's typed results through JSON and back: an entry, the base re-fit, the final fit, the localisation,
the whole diagnosis (``from_json(to_json(x))`` equal to ``x``, arrays compared with numpy)."""

import dataclasses
import json

import numpy as np
import pytest

from jaxheli.data.flight import FlightData
from jaxheli.effects import registry as effects
from jaxheli.gap.fit_effect import EffectFit
from jaxheli.gap.localisation_record import Localisation
from jaxheli.gap.localise import localise
from jaxheli.gap.records import Attribution, Diagnosis, Entry, Final, FlightSummary, Gap, Refit
from jaxheli.gap.significance import HeldOut, shrink_entries
from jaxheli.model import TABLE2
from jaxheli.synth.piloted import DEFAULT_OUTPUTS

OUT = DEFAULT_OUTPUTS


def _entries() -> list[Entry]:
    """Two ranking entries of a delay and a lag (fitted nuisance values included) behind a reference row."""
    k = 2 * len(OUT) + 1
    z = np.zeros((3, k))
    z[1, :4], z[2, :4], z[:, -1] = [0.08, 0.0, 0.01, 0.0], [0.05, 0.02, 0.0, 0.0], [0.0, -0.3, 0.2]
    fit = EffectFit(z=z, stderr=np.full((3, k), 0.005), theta=np.tile(TABLE2, (3, 1)) * [[1.0], [1.01], [0.99]],
              rss=np.array([1.0, 0.6, 0.7]), n_eff=np.full(3, 100.0), k_active=np.array([1, 5, 5]),
              steps=np.array([4, 5, 6]), converged=np.array([True, True, False]))
    segs = np.random.default_rng(0).uniform(1.0, 2.0, (3, 8)) * np.array([[1.0], [0.6], [0.7]])
    gaps = np.sum(segs, axis=1, keepdims=True) * np.linspace(0.5, 1.5, len(OUT)) / 8
    return shrink_entries(["input_delay", "actuator_lag"], OUT, fit, HeldOut(gaps, segs), 3.0, shared=True)


def _localisation(seed: int) -> Localisation:
    """A localisation of noise against noise (sticks held constant: none of the few Welch bins of the top band)
    with a frequency response holding an undefined (``None``) entry, as :func:`localise_prediction` gives it."""
    rng = np.random.default_rng(seed)
    n, dt = 400, 0.05
    inputs = np.cumsum(rng.normal(size=(n, 4)), axis=0)
    inputs[:, 3] = 0.0
    measured = rng.normal(size=(n, 2))
    flight = FlightData(dt * np.arange(n), inputs, measured, ("p", "q"), source=f"flight{seed}")
    found = localise(flight, measured - rng.normal(size=(n, 2)), bands=(0.0, 1.0, 9.99, None))
    return dataclasses.replace(found, frequency_response={"lat->p": {"bins": 3.0, "magnitude_db": None}},
                               simulation={"g": 9.81, "hold": "zoh"})


def _diagnosis() -> Diagnosis:
    best, lag = _entries()
    combination = dataclasses.replace(best, effect="input_delay+actuator_lag", shrink_se_pct=float("inf"))
    refit = Refit(shrink_pct=12.0, shrink_se_pct=2.5, gap_base=0.4, gap=0.35, gap_by_channel=dict.fromkeys(OUT, 0.35),
                  under_fitted=True, converged=False, progress_pct=0.3, settled=True, steps=160,
                  theta=np.asarray(TABLE2) * 1.02, nuisance={"state_noise_cut": -0.1})
    final = Final(best.effect, best.fitted, rss=12.5, steps=60, theta=np.asarray(TABLE2) * 0.98,
                  nuisance={"state_noise_cut": 0.2})
    attribution = Attribution((best, lag), combination, refit, final, 0.3)
    flights = {role: FlightSummary(f"{role}.npz", 401, 0.05, ({"step": "trim", "samples": 2},))
               for role in ("train", "validate")}
    gap = Gap(dict.fromkeys(OUT, 0.2), 0.2)
    return Diagnosis("table2", flights, OUT, 2.0, ({"kind": "time_scale", "flight": "train"},), _localisation(1),
                     attribution, gap, dataclasses.replace(gap, total=0.1), dataclasses.replace(gap, total=float("nan")),
                     _localisation(2))


def _assert_entry_equal(a: Entry | Final, b: Entry | Final) -> None:
    for field in dataclasses.fields(a):
        x, y = getattr(a, field.name), getattr(b, field.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y)
        elif isinstance(x, float):
            np.testing.assert_equal(x, y)
        else:
            assert x == y, field.name


def test_an_entry_comes_back_from_json():
    for entry in _entries():
        text = json.dumps(entry.to_json())
        _assert_entry_equal(Entry.from_json(json.loads(text)), entry)
    best = _entries()[0]
    assert best.effect == "input_delay" and best.nuisance == {"state_noise_cut": -0.3}
    assert best.fitted.params["delay_lat"].interval[0] < best.fitted.params["delay_lat"].value


def test_a_diagnosis_comes_back_from_strict_json():
    """Through strict JSON (non-finite numbers written as ``null``, read back as NaN): every record equal, the
    JSON the same again."""
    d = _diagnosis()
    content = json.loads(json.dumps(d.to_json(), allow_nan=False))
    assert content["combination"]["shrink_se_pct"] is None and content["gap_after"]["combination"]["total"] is None
    assert content["gap_after"]["best"]["effect"] == "input_delay" and content["base_refit"]["joint"]
    back = Diagnosis.from_json(content)
    assert back.to_json() == content
    a, b = d.attribution, back.attribution
    for x, y in zip((*a.ranking, a.final), (*b.ranking, b.final)):
        _assert_entry_equal(x, y)
    assert b.combination.shrink_se_pct != b.combination.shrink_se_pct  # inf written as null: NaN
    for field in ("shrink_pct", "gap_by_channel", "under_fitted", "settled", "steps", "nuisance"):
        assert getattr(b.base_refit, field) == getattr(a.base_refit, field), field
    np.testing.assert_array_equal(b.base_refit.theta, a.base_refit.theta)
    assert (str(b.verdict), b.track, back.outputs, back.flights, back.consistency) == (
        str(a.verdict), a.track, d.outputs, d.flights, d.consistency)
    assert content["verdict"] == str(a.verdict) and b.verdict.effect.effect == a.verdict.effect.effect
    assert (back.localisation, back.localisation_train) == (d.localisation, d.localisation_train)
    assert content["localisation"]["train"] == d.localisation_train.to_json()
    assert content["localisation"]["frequency_response"]["lat->p"]["magnitude_db"] is None
    assert back.localisation.band[-1].coherence["p"] is None  # no Welch bin above 9.99 Hz
    assert (back.gap_before, back.gap_best) == (d.gap_before, d.gap_best) and np.isnan(back.gap_combination.total)


def test_a_frozen_base_writes_no_refit_and_reads_none():
    d = _diagnosis()
    frozen = dataclasses.replace(d, attribution=dataclasses.replace(d.attribution, base_refit=None, final=None,
                                                                    combination=None), gap_combination=None)
    content = frozen.to_json()
    assert content["base_refit"] == {"joint": False} and content["final"] is None
    assert content["gap_after"]["combination"] is None
    back = Diagnosis.from_json(content).attribution
    assert back.base_refit is None and back.final is None and back.combination is None
    untrained = dataclasses.replace(d, localisation_train=None)
    assert "train" not in untrained.to_json()["localisation"]
    assert Diagnosis.from_json(untrained.to_json()).localisation_train is None


def test_a_fitted_parameter_keeps_its_interval():
    estimate = effects.describe("input_delay", OUT, np.array([0.05, 0, 0, 0]), np.full(4, 0.01))[0]["delay_lat"]
    assert effects.Estimate.from_json(json.loads(json.dumps(estimate.to_json()))) == estimate
    assert estimate.interval == pytest.approx((0.05 - 1.959964 * 0.01, 0.05 + 1.959964 * 0.01))
