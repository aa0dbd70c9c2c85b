"""The named effect's size: re-identified with the base model on the training and validation flights together.

The ranking decides *which* effect on held-out data: every candidate is fitted on the training flight and scored
on the validation flight (:mod:`jaxheli.gap.ranking`). Its size from the training flight alone falls short where
the base model, identified on the same contaminated flight, kept part of the effect and the flight cannot tell
the two apart. Once the effect is named, the validation flight has done its part, and its other excitation (larger
sticks, other manoeuvres) tells the effect from the base parameters it trades with, a quadratic drag from the
linear damping by amplitude: the effect and the base model are re-fitted on both flights at once, from the
training fit. Nothing in the ranking or the verdict depends on this fit.
"""

from __future__ import annotations

import dataclasses
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..bounds import Bounds
from ..effects import registry as fx
from ..effects.plant import no_effect
from .fit_effect import effect_eta, fit_candidates, fitted_nuisance, with_reference
from .predictor import Predictor
from .candidate_records import Entry, Final


class Stacked(eqx.Module):
    """Predictors of several flights fitted as one record: their residuals concatenated, their measurements stacked
    in time (what :func:`~jaxheli.gap.fit_effect.fit_candidates` reads of a predictor)."""

    flights: tuple[Predictor, ...]

    @property
    def outputs(self) -> tuple[str, ...]:
        return self.flights[0].outputs

    def for_walks(self, walks: bool) -> Stacked:
        """Every flight's predictor with the bias states in its filter or not (:meth:`Predictor.for_walks`)."""
        return Stacked(tuple(p.for_walks(walks) for p in self.flights))

    def residuals(self, theta: Float[Array, "40"], eta: Float[Array, "E"]) -> Float[Array, " M"]:
        """Every flight's normalised output errors (:meth:`Predictor.residuals`), one after the other."""
        return jnp.concatenate([p.residuals(theta, eta) for p in self.flights])

    @property
    def measured(self) -> Float[Array, "N k"]:
        return jnp.concatenate([p.measured for p in self.flights])


def final_fit(train: Predictor, validate: Predictor, entry: Entry, box: Bounds, max_steps: int = 60) -> Final:
    """``entry``'s effect (a ranking entry or combination, jointly fitted: with its ``theta`` and ``nuisance``)
    and the base parameters re-fitted on ``train`` and ``validate`` together (Levenberg-Marquardt, ``max_steps``,
    the base parameters in ``box``, the effect in its physical box), started from the entry's fit (``rss`` over
    both flights)."""
    outputs = train.outputs
    index, start, lower, upper = fx.candidate_arrays(entry.effect.split("+"), outputs, combine=True)
    cand = jax.tree.map(lambda a: a[1:], with_reference(index, start, lower, upper, len(no_effect(outputs)),
                                                         fx.nuisance_arrays(outputs)))
    eta = np.r_[effect_eta(entry.effect, entry.fitted.params, outputs, entry.nuisance), 0.0]
    cand = dataclasses.replace(cand, start=jnp.clip(jnp.asarray(eta)[cand.index], cand.lower, cand.upper))
    fit = fit_candidates(Stacked((train, validate)), jnp.asarray(entry.theta), jnp.asarray(no_effect(outputs)), cand,
                         max_steps, box, once=True)
    value = np.asarray(fit.z[0])
    fitted = fx.report(entry.effect, outputs, value, np.asarray(fit.stderr[0]))
    return Final(entry.effect, fitted, float(fit.rss[0]), int(fit.steps[0]), np.asarray(fit.theta[0], np.float64),
                 fitted_nuisance(value, outputs, fitted.params))
