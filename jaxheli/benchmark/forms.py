"""How far each kind of the independent truth simulator lies from the nearest candidate form of the catalogue.

A kind's noise-free effect (:mod:`jaxheli.benchmark.truth`, flown on its own hover model with no sensor noise) is
predicted the way the diagnosis predicts a flight (:func:`~jaxheli.gap.predictor.make_predictor`: restarts every
:data:`~jaxheli.gap.predictor.SEGMENT` s as :data:`~jaxheli.gap.predictor.RESTART`, the restart filter set to the
sensor noise), by the truth's own 40 parameters with each candidate that counts as naming the kind fitted alone (from
each of its starts, in its physical box). The residual left by the best candidate, in units of each channel's sensor
noise, says whether the kind is in a candidate's family (below 1: the candidate reproduces it within the noise) or
in a form of its own (above 1). The same ratio with no effect fitted is the kind's size.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize

from ..data.flight import FlightData
from .._xla import quick_jit
from ..effects import registry as fx
from ..effects.plant import no_effect
from ..gap.predictor import RESTART, SEGMENT, Predictor, make_predictor, smooths, tune_track
from . import truth

_WALKING = "output_bias_drift"
"""The candidate whose walk is a state of the restart filter (:meth:`Predictor.for_walks`)."""


@dataclasses.dataclass(frozen=True)
class FormGap:
    """A kind's ``size`` (no effect fitted) and the ``residual`` left by its ``nearest`` candidate (fitted values
    ``values``), each ``max_k rms_t(prediction - reading) / sigma_k`` over the noise-free flight."""

    size: float
    residual: float
    nearest: str
    values: dict[str, float]

    @property
    def in_family(self) -> bool:
        """The nearest candidate reproduces the effect within the sensor noise."""
        return self.residual <= 1.0


def form_gap(theta: np.ndarray, effects: truth.Effects, candidates: tuple[str, ...], *, style: str, seed: int,
             duration: float = 30.0, dt: float = 0.05, outputs: tuple[str, ...] = truth.OUTPUTS,
             noise: float = 1.0) -> FormGap:
    """The :class:`FormGap` of ``effects`` on the truth ``theta`` (40 parameters) flown with excitation ``style``
    from ``seed`` for ``duration`` s logged every ``dt`` s, against ``candidates`` (library effect names), sensor
    noise ``noise`` times :data:`~jaxheli.benchmark.truth.NOISE`."""
    sigma = np.array([noise * truth.NOISE[c] for c in outputs])
    flown = truth.fly(theta, effects, style=style, duration=duration, dt=dt, seed=seed, noise=sigma, outputs=outputs)
    pred = noise_free_predictor(flown, sigma, tuple(outputs), theta)
    base = no_effect(tuple(outputs))
    size = residual_ratio(pred.for_walks(False), theta, base, sigma)
    best = FormGap(size, size, "none", {})
    for name in (c for c in candidates if c != "none"):
        fitted, values = _fit(pred.for_walks(name == _WALKING), theta, base, name, tuple(outputs), sigma)
        residual = residual_ratio(pred.for_walks(name == _WALKING), theta, fitted, sigma)
        if residual < best.residual:
            best = FormGap(size, residual, name, values)
    return best


def in_family(dt: float) -> dict[str, tuple[truth.Effects, tuple[str, ...]]]:
    """Controls in a candidate's own form, with the candidates that name them: a link delay of three whole frames of
    ``dt`` s (``input_delay``) and a gyro triad and velocity frame turned in yaw alone, with gyro scale errors
    (``sensor_misalignment``). Their residual must stay within the noise, or the fit, not the form, is at fault."""
    return {
        "whole_frame_delay": (truth.Effects(servo=truth.Servo(delay=(3 * dt,) * 4)), ("input_delay",)),
        "yaw_misalignment": (truth.Effects(imu=truth.Imu(yaw=np.deg2rad(5.0), scale=(0.05, -0.04, 0.0),
                                                         velocity_yaw=np.deg2rad(4.0))), ("sensor_misalignment",)),
    }


def kind_gap(kind: str, seed: int, theta: np.ndarray, *, style: str = "sweep", strength: float = 1.0,
             duration: float = 30.0, dt: float = 0.05, outputs: tuple[str, ...] = truth.OUTPUTS) -> FormGap:
    """The :class:`FormGap` of a draw of ``kind`` (:data:`~jaxheli.benchmark.truth.KINDS`) at ``strength`` from
    ``seed`` (a stream of its own: not the blind check's draw of that seed) against the candidates that count as
    naming it."""
    noise = {c: truth.NOISE[c] for c in outputs}
    dice = truth.Dice(np.random.default_rng([seed, truth.KINDS.index(kind), 1]), strength, noise, duration, dt,
                      tuple(outputs))
    injected = truth.draw(kind, dice)
    return form_gap(theta, injected.effects, injected.candidates, style=style, seed=seed, duration=duration, dt=dt,
                    outputs=outputs)


def noise_free_predictor(record: truth.Record, sigma: np.ndarray, outputs: tuple[str, ...], theta: np.ndarray
                         ) -> Predictor:
    """The diagnosis's predictor (:func:`~jaxheli.gap.predictor.make_predictor`: restarts every
    :data:`~jaxheli.gap.predictor.SEGMENT` s as :data:`~jaxheli.gap.predictor.RESTART`) of ``record``'s noise-free
    readings of ``outputs``, its restart filter set to the sensor noise ``sigma`` (per channel) and tuned to the
    truth ``theta``."""
    flight = FlightData(record.time, record.sticks, record.clean, tuple(outputs), source="noise-free truth flight")
    pred = make_predictor(flight, segment=SEGMENT, smooth=smooths(RESTART, "noise_free_predictor"))
    pred = dataclasses.replace(pred, noise_var=jnp.asarray(sigma**2))
    return dataclasses.replace(pred, track=jnp.asarray(tune_track(pred, jnp.asarray(theta))))


def residual_ratio(pred: Predictor, theta: np.ndarray, eta: np.ndarray, sigma: np.ndarray) -> float:
    """``max_k rms_t(pred(theta, eta) - reading) / sigma_k`` over ``pred``'s readings."""
    y = np.asarray(_predict(pred, jnp.asarray(theta), jnp.asarray(eta)))
    return float(np.max(np.sqrt(np.mean((y - np.asarray(pred.measured)) ** 2, axis=0)) / sigma))


@quick_jit
def _predict(pred: Predictor, theta: jax.Array, eta: jax.Array) -> jax.Array:
    """``pred(theta, eta)``, compiled."""
    return pred(theta, eta)


def _fit(pred: Predictor, theta: np.ndarray, base: np.ndarray, name: str, outputs: tuple[str, ...],
         sigma: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
    """Candidate ``name``'s parameters fitted alone (least squares in its box, from each of its starts) to the
    predictor's readings with the truth's ``theta``: the best ``eta`` and its named values. Every candidate but the
    walking bias pads to the widest of them, so one compiled program serves them all."""
    n = len(fx.params(name, outputs))
    width = n if name == _WALKING else max(len(fx.params(c, outputs)) for c in fx.ALL if c != _WALKING)
    index, _, lower, upper = (a[0] for a in fx.candidate_arrays([name], outputs, shape=(1, width)))
    scale = np.tile(sigma, pred.measured.shape[0])
    args = (pred, jnp.asarray(theta), jnp.asarray(base), jnp.asarray(index), jnp.asarray(scale))

    def padded(z: np.ndarray) -> jax.Array:
        return jnp.asarray(np.concatenate([z, np.zeros(width - n)]))

    fits = [scipy.optimize.least_squares(lambda z: np.asarray(_residuals(padded(z), *args)), start,
                                         jac=lambda z: np.asarray(_jacobian(padded(z), *args))[:, :n],
                                         bounds=(lower[:n], upper[:n]), max_nfev=_STEPS)
            for start in np.clip(fx.start_rows(name, outputs), lower[:n], upper[:n])]
    z = min(fits, key=lambda f: f.cost).x
    eta = _eta(padded(z), jnp.asarray(base), jnp.asarray(index))
    return np.asarray(eta), {p.name: float(v) for p, v in zip(fx.params(name, outputs), z)}


_STEPS = 30
"""Function evaluations of each start's least-squares fit."""


def _eta(z: jax.Array, base: jax.Array, index: jax.Array) -> jax.Array:
    """``base`` with the slots ``index`` set to ``z`` (padding slot ``E`` dropped)."""
    return jnp.concatenate([base, jnp.zeros(1)]).at[index].set(z)[:-1]


def _errors(z: jax.Array, pred: Predictor, theta: jax.Array, base: jax.Array, index: jax.Array,
               scale: jax.Array) -> jax.Array:
    """Readings predicted with the candidate values ``z`` minus those of the flight, over the sensor noise."""
    return (pred(theta, _eta(z, base, index)) - pred.measured).reshape(-1) / scale


_residuals = quick_jit(_errors)
_jacobian = quick_jit(jax.jacfwd(_errors))
