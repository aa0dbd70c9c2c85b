"""How much of a truth trial's effect a hover model alone can take up: the effect's imprint beyond the structure.

A diagnosis whose base model is wrong tests the base model's structure first (the 40 parameters re-fitted in the
physical ranges) and credits an effect only for what it explains beyond that re-fit. Where a hover model, fitted to
the training flight, already predicts the held-out flight with the effect to within the sensor noise, no diagnosis
can tell the effect from a different hover model on these flights. This module decides that from the truth
simulator's noise-free readings, apart from any method's fit to the noisy data: the 40 parameters are fitted by least
squares in the physical box (:func:`~jaxheli.bounds.named_box` ``"wide"``), from the truth's own values, to the
noise-free training readings, predicted the way the diagnosis predicts a flight
(:func:`~jaxheli.benchmark.forms.noise_free_predictor`), and the noise-free validation readings are predicted with
them. The residual left there, ``max_k rms_t(prediction - reading) / sigma_k``, above 1 says the effect lies beyond
the structure's reach.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize

from .._types import Array, Float
from .._xla import quick_jit
from ..bounds import named_box
from ..effects.plant import no_effect
from ..gap.predictor import Predictor
from .forms import noise_free_predictor, residual_ratio
from .truth import Record

STEPS = 40
"""Function evaluations of the hover model's least-squares fit to the noise-free training readings."""


@dataclasses.dataclass(frozen=True)
class StructureReach:
    """The effect's size on the validation flight with the truth's own hover model (``size``), and the residual
    there once the hover model was fitted to the training flight (``beyond``), both ``max_k rms_t(prediction -
    reading) / sigma_k`` over the noise-free readings; ``train`` is that fit's residual on its own flight."""

    size: float
    beyond: float
    train: float

    @property
    def reachable(self) -> bool:
        """A hover model fitted to the training flight predicts the validation flight within the sensor noise."""
        return self.beyond <= 1.0


def structure_reach(theta: Float[np.ndarray, "40"], train: Record, validate: Record, sigma: Float[np.ndarray, "k"],
                    outputs: tuple[str, ...]) -> StructureReach:
    """:class:`StructureReach` of the noise-free ``train`` and ``validate`` flights (:class:`~.truth.Record`) of
    the truth ``theta`` (40 parameters), their sensor-noise std ``sigma`` per channel of ``outputs``."""
    sigma = np.asarray(sigma, dtype=np.float64)
    fit_pred, val_pred = (noise_free_predictor(record, sigma, outputs, theta) for record in (train, validate))
    box = named_box("wide")
    lower, upper = np.asarray(box.lower, np.float64), np.asarray(box.upper, np.float64)
    base = jnp.asarray(no_effect(tuple(outputs)))
    scale = jnp.asarray(np.tile(sigma, fit_pred.measured.shape[0]))
    start = np.clip(np.asarray(theta, np.float64), lower, upper)
    fitted = scipy.optimize.least_squares(
        lambda z: np.asarray(_residuals(jnp.asarray(z), fit_pred, base, scale)), start,
        jac=lambda z: np.asarray(_jacobian(jnp.asarray(z), fit_pred, base, scale)), bounds=(lower, upper),
        max_nfev=STEPS, x_scale="jac").x
    return StructureReach(size=residual_ratio(val_pred, theta, base, sigma),
                          beyond=residual_ratio(val_pred, fitted, base, sigma),
                          train=residual_ratio(fit_pred, fitted, base, sigma))


def _errors(theta: Float[Array, "40"], pred: Predictor, base: Float[Array, "E"], scale: Float[Array, "M"]
            ) -> Float[Array, "M"]:
    """Readings predicted by the hover model ``theta`` (no effect) minus the flight's, over the sensor noise."""
    return (pred(theta, base) - pred.measured).reshape(-1) / scale


_residuals = quick_jit(_errors)
_jacobian = quick_jit(jax.jacfwd(_errors))
