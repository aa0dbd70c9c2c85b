"""The yardstick's challenge: a candidate's base parameters that lead to a better basin replace the reference."""

import dataclasses

import jax.numpy as jnp
import numpy as np

from jaxheli.effects import registry as fx
from jaxheli.effects.plant import no_effect
from jaxheli.gap.fit_effect import embed, score, with_reference
from jaxheli.gap.ranking import fit_and_score, predictor_pair
from jaxheli.gap.reference import base_refit, challenge, theta_box
from jaxheli.gap.significance import HeldOut
from jaxheli.model import TABLE2
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import DEFAULT_OUTPUTS, piloted_flight

OUT = DEFAULT_OUTPUTS
SHORT = Excitation("3211", amplitude=(0.2, 0.2, 0.2, 0.2), unit=0.4)
STEPS = 3


def _flight(seed: int):
    return piloted_flight(TABLE2, duration=16.0, dt=0.05, excitation=SHORT, seed=seed, noise=1.0)


def test_a_challenger_in_a_better_basin_replaces_the_reference_and_is_recorded():
    # a base far from the truth, re-fitted a few steps: the reference sits in a poor basin; candidate 1's base
    # parameters are set to the truth's, standing for a joint fit that found the better one
    train, validate = predictor_pair(TABLE2, _flight(1), _flight(2), segment=3.0)
    poor = np.asarray(TABLE2) * np.where(np.arange(40) % 3 == 0, 1.4, 0.7)
    box = theta_box(poor, theta_box(TABLE2))
    cand = with_reference(*fx.candidate_arrays(["input_delay", "output_bias_drift"], OUT), len(no_effect(OUT)),
                          fx.nuisance_arrays(OUT))
    fitted = fit_and_score(train, validate, poor, cand, STEPS, box)
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
    # the reference's validation score is its new fit's
    base = jnp.asarray(no_effect(OUT))
    want = np.asarray(score(validate, got.fit.theta[:1], embed(base, cand.index[0], got.fit.z[0])[None])[0])
    np.testing.assert_allclose(got.rows.gap[0], want[0], rtol=1e-9)
