"""The yardstick's challenge: a candidate's base parameters that lead to a better basin replace the reference, and
the candidates are then fitted from that basin too."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.effects import registry as fx
from jaxheli.effects.plant import no_effect
from jaxheli.gap.fit_effect import embed, score, with_reference
from jaxheli.gap.candidates import challenge, fit_and_score, follow
from jaxheli.gap.ranking import predictor_pair
from jaxheli.gap.reference import Scored, base_refit, refit_alone, theta_box
from jaxheli.gap.significance import HeldOut
from jaxheli.model import TABLE2
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import DEFAULT_OUTPUTS, piloted_flight

OUT = DEFAULT_OUTPUTS
SHORT = Excitation("3211", amplitude=(0.2, 0.2, 0.2, 0.2), unit=0.4)
STEPS = 3
BASE = jnp.asarray(no_effect(OUT))


def _flight(seed: int):
    return piloted_flight(TABLE2, duration=16.0, dt=0.05, excitation=SHORT, seed=seed, noise=1.0)


@pytest.fixture(scope="module")
def poor_basin():
    """Two flights' predictors, the box, two candidates behind the reference, and their fits from a base far from
    the truth, re-fitted a few steps: the reference and the candidates sit in a poor basin."""
    train, validate = predictor_pair(TABLE2, _flight(1), _flight(2), segment=3.0)
    poor = np.asarray(TABLE2) * np.where(np.arange(40) % 3 == 0, 1.4, 0.7)
    box = theta_box(poor, theta_box(TABLE2))
    cand = with_reference(*fx.candidate_arrays(["input_delay", "output_bias_drift"], OUT), len(no_effect(OUT)),
                          fx.nuisance_arrays(OUT))
    return train, validate, box, cand, fit_and_score(train, validate, poor, cand, STEPS, box)


def _reference_score(validate, fit, row, cand):
    return np.asarray(score(validate, fit.theta[row:row + 1], embed(BASE, cand.index[0], fit.z[row])[None])[0])[0]


def test_a_challenger_in_a_better_basin_replaces_the_reference_and_is_recorded(poor_basin):
    # candidate 1's base parameters are set to the truth's, standing for a joint fit that found the better basin
    train, validate, box, cand, fitted = poor_basin
    assert not fitted.moved and not base_refit(fitted, OUT, 5.0).challenged
    fit = dataclasses.replace(fitted.fit, theta=fitted.fit.theta.at[1].set(jnp.asarray(TABLE2)))
    gap = fitted.rows.gap.copy()
    gap[1:] = 2.0 * gap[0]
    # no candidate shrinks the held-out gap: nothing challenges the reference
    idle = fitted._replace(fit=fit, rows=HeldOut(gap, fitted.rows.energy))
    assert challenge(train, validate, cand, idle, STEPS, box, 2) is idle
    gap[1] = 0.5 * gap[0]
    scored = fitted._replace(fit=fit, rows=HeldOut(gap, fitted.rows.energy))
    got = challenge(train, validate, cand, scored, STEPS, box, 2)
    assert got.moved and base_refit(got, OUT, 5.0).challenged
    old, new = float(fit.rss[0]), float(got.fit.rss[0])
    assert new < 0.9 * old
    # the candidates keep their fits and scores; the reference's RSS and where the candidates started move together
    np.testing.assert_array_equal(np.asarray(got.fit.rss[1:]), np.asarray(fit.rss[1:]))
    np.testing.assert_array_equal(got.rows.gap[1:], gap[1:])
    np.testing.assert_allclose(got.rss_start, fitted.rss_start - (old - new), rtol=1e-12)
    np.testing.assert_allclose(got.rows.gap[0], _reference_score(validate, got.fit, 0, cand), rtol=1e-9)


def test_candidates_follow_a_reference_that_moved_to_a_better_basin(poor_basin):
    # the reference re-fitted from the truth stands for a challenger that found the better basin
    train, validate, box, cand, before = poor_basin
    better = refit_alone(train, jnp.asarray(TABLE2), jax.tree.map(lambda a: a[:1], cand), STEPS, box)
    assert float(better.rss[0]) < float(before.fit.rss[0])
    gap, energy = before.rows.gap.copy(), before.rows.energy.copy()
    gap[0] = _reference_score(validate, better, 0, cand)
    after = Scored(jax.tree.map(lambda a, b: a.at[0].set(b[0]), before.fit, better), before.given,
                   HeldOut(gap, energy), before.rss_start, moved=True)

    assert follow(train, validate, cand, before, STEPS, box) is before
    got = follow(train, validate, cand, after, STEPS, box)
    old, new = np.asarray(before.fit.rss), np.asarray(got.fit.rss)
    # the reference stays the challenger's; each candidate keeps the better of its two fits, here the new basin's
    assert new[0] == float(better.rss[0]) and got.moved and got.followed == 2 and base_refit(got, OUT, 5.0).followed == 2
    assert np.all(new[1:] < 0.9 * old[1:])
    # its validation scores are those of the fit it kept, not of the fit it left
    etas = jax.vmap(lambda i, z: embed(BASE, i, z))(cand.index, got.fit.z)
    want = np.asarray(score(validate, got.fit.theta, etas)[0])
    np.testing.assert_allclose(got.rows.gap[1:], want[1:], rtol=1e-9)
    np.testing.assert_array_equal(got.rows.gap[0], gap[0])
    assert not np.allclose(got.rows.gap[1:], before.rows.gap[1:])
    # a challenge the candidates cannot gain from leaves them as they were
    worse = dataclasses.replace(before.fit, rss=before.fit.rss.at[1:].set(0.0))
    same = follow(train, validate, cand, after._replace(fit=jax.tree.map(lambda a, b: a.at[0].set(b[0]), worse,
                                                                          better)), STEPS, box)
    np.testing.assert_array_equal(same.rows.gap, after.rows.gap)
    assert same.followed == 0
