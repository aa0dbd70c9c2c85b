"""The named effect re-identified on both flights: stacked residuals, and a drag recovered from a base model that
kept part of it."""

import numpy as np
import pytest

from jaxheli.effects import plant as augmented, registry as effects
from jaxheli.gap.final_fit import Stacked, final_fit
from jaxheli.gap.ranking import predictor_pair
from jaxheli.gap.reference import theta_box
from jaxheli.gap.significance import HeldOut, shrink_entries
from jaxheli.gap.fit_effect import EffectFit
from jaxheli.model import PARAM_NAMES, TABLE2
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import DEFAULT_OUTPUTS, piloted_flight

OUT = DEFAULT_OUTPUTS
XUU = -4.0


def _drag_flights():
    eta = augmented.no_effect(OUT)
    eta[next(p.slot for p in effects.params("quadratic_drag", OUT) if p.name == "Xuu")] = XUU
    common = dict(duration=20.0, dt=0.05, effect=eta, noise=0.1)
    train = piloted_flight(TABLE2, excitation=Excitation("3211", amplitude=(0.1,) * 4, unit=0.3), seed=1, **common)
    validate = piloted_flight(TABLE2, excitation=Excitation("3211", amplitude=(0.25,) * 4, unit=0.35), seed=2,
                              **common)
    return train, validate


def test_stacked_flights_are_their_residuals_one_after_the_other():
    train, validate = predictor_pair(TABLE2, *_drag_flights(), segment=2.0)
    eta = augmented.no_effect(OUT)
    both = Stacked((train, validate))
    parts = [np.asarray(p.residuals(TABLE2, eta)) for p in (train, validate)]
    np.testing.assert_array_equal(np.asarray(both.residuals(TABLE2, eta)), np.concatenate(parts))
    assert both.measured.shape == (train.measured.shape[0] + validate.measured.shape[0], len(OUT))


def test_a_drag_half_kept_by_the_base_model_is_recovered_on_both_flights():
    """Table 2 with a quadratic drag Xuu = -4 1/m on both flights (faint noise). The entry handed over is what a
    training fit leaves when the base model kept part of the drag: Xu 30 % too negative, the drag at half. Re-fitted
    on both flights, the drag comes back within 3 % of -4 (measured: -3.94) and Xu within 10 % of Table 2's (8 %)."""
    train, validate = predictor_pair(TABLE2, *_drag_flights(), segment=2.0, track=0.1)
    start = np.array(TABLE2)
    xu = PARAM_NAMES.index("Xu")
    start[xu] *= 1.3
    final = final_fit(train, validate, _entry(start), theta_box(start))
    assert final.effect == "quadratic_drag" and final.fitted.at_bound == ()
    assert final.fitted.params["Xuu"].value == pytest.approx(XUU, rel=0.03)
    assert final.theta[xu] == pytest.approx(TABLE2[xu], rel=0.1)
    assert final.fitted.evidence_z > 2.0 and "Xuu" in final.fitted.summary


def _entry(theta):
    """The ranking entry of a drag fitted at half its size (``Xuu = -2``, ``Yvv = 0``) with base parameters
    ``theta``."""
    k = len(effects.params("quadratic_drag", OUT))
    z = np.zeros((2, k))
    z[1, [p.name for p in effects.params("quadratic_drag", OUT)].index("Xuu")] = XUU / 2
    fit = EffectFit(z=z, stderr=np.full((2, k), 0.1), theta=np.stack([theta, theta]), rss=np.ones(2), n_eff=np.ones(2),
              k_active=np.zeros(2, int), steps=np.ones(2, int), converged=np.ones(2, bool))
    (entry,) = shrink_entries(["quadratic_drag"], OUT, fit, HeldOut(np.ones((2, len(OUT))), np.ones((2, 4))), 10.0)
    return entry
