"""Segment-wise predictor of a flight under the augmented plant: the yardstick of every candidate effect.

Every candidate (and the base model) is scored the same way: the augmented plant is simulated on the
recorded sticks and restarted every ``segment`` seconds from the state a steady-state Kalman filter of the
same candidate plant estimates from the sensor readings up to the restart (measurements passed back
through the candidate's sensor model, :meth:`Plant.unmeasure`). Restarting from raw readings instead
injects their noise into every segment, where it makes fitted delays and rotor time constants wander. The
filter follows the measurements with process noise ``track`` times the measurement noise per sample;
the diagnosis tunes ``track`` on the training flight (:func:`tune_track`): low when the model is close,
high when it is far from the flight (identified models of real flights), so restarts stay near the data.
The process-noise candidate adds its gust states to the filter: the wind it estimates restarts with the
states and then decays with the gust time constant inside the segment. The bias candidate's walk adds a bias state
per output channel: the bias it estimates restarts with the states and reverts inside the segment at the walk's
reversion rate (held, as a random walk's, at a rate of 0).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..cost import nmse
from ..data.flight import FlightData
from ..problem import Problem
from ..model import FLAPPING, G_SI, N_STATES, output_indices
from ..effects.plant import GUST_STATES, make_plant, no_effect
from .kalman import gust_filter
from .segment_restart import restart_correction
from .thresholds import THRESHOLDS


_ANCHOR = 1e6
"""Prior information of each walking bias at the record's start (where the walk is zero: the bias is the fitted
fixed bias), per unit of its channel's noise information: the first segment's restart may not move the biases, so
that a fixed bias is told apart from the walk (re-estimated from the segment, the walk absorbed any fixed bias)."""


class Predictor(eqx.Module):
    """One flight's arrays and settings; ``pred(theta, eta) -> outputs[N, k]``. Build with :func:`make_predictor`."""

    inputs: Float[Array, "N 4"]
    measured: Float[Array, "N k"]
    time: Float[Array, "N"]
    noise_var: Float[Array, "k"]
    scale: Float[Array, "k"]
    dt: float = eqx.field(static=True)
    segment_samples: int = eqx.field(static=True)
    window_samples: int = eqx.field(static=True)
    outputs: tuple[str, ...] = eqx.field(static=True)
    g: float = eqx.field(static=True)
    max_delay: float = eqx.field(static=True)
    track: Float[Array, ""]
    smooth: bool = eqx.field(static=True, default=False)
    walks: bool = eqx.field(static=True, default=True)
    """Whether the restart filter carries the output biases' states (:func:`~jaxheli.gap.kalman.gust_filter`); ``False``
    is exact only for effects whose walks are all zero (:meth:`for_walks`)."""

    def for_walks(self, walks: bool) -> Predictor:
        """This predictor with the bias states in its filter (``walks``) or not: the fits and scores of effects that
        walk no bias (the base model, every other candidate) run the smaller filter; with no walk, the bias states
        move the predictions by about ``1e-6`` of the readings per sample of floor gain."""
        return dataclasses.replace(self, walks=bool(walks))

    def __call__(self, theta: Float[Array, "40"], eta: Float[Array, "E"]) -> Float[Array, "N k"]:
        plant = make_plant(theta, eta, self.dt, self.outputs, g=self.g, max_delay=self.max_delay)
        F, H, K, P = gust_filter(plant, self.noise_var, self.track, self.walks)
        idx = jnp.asarray(output_indices(self.outputs))
        k, gusts = len(self.outputs), slice(N_STATES, N_STATES + len(GUST_STATES))
        b = k if self.walks else 0
        rho = F[gusts.start, gusts.start]
        rho_bias = F[gusts.stop, gusts.stop] if self.walks else 1.0
        states = plant.unmeasure(self.measured, self.time)
        x0 = jnp.zeros(N_STATES).at[idx].set(states[0])
        history, servo, rotor = plant.init_actuators()

        def step(carry, inp):
            x, wind, bias, history, servo, rotor, z = carry
            stick, after, restart = inp
            history, servo = plant.actuate(history, servo, stick)
            x_next, rotor_next = plant.advance(x, rotor, servo, wind)
            z_x, _ = plant.advance(z[:N_STATES], rotor, servo, z[gusts])
            z = jnp.concatenate([z_x, rho * z[gusts], rho_bias * z[gusts.stop:]])
            z = z + K @ (after - H @ z)
            out = x_next[idx] + bias
            x_next = jnp.where(restart, z[:N_STATES], x_next)
            wind = jnp.where(restart, z[gusts], rho * wind)
            bias = jnp.where(restart, z[gusts.stop:], rho_bias * bias) if self.walks else bias
            return (x_next, wind, bias, history, servo, rotor_next, z), out

        restart = jnp.arange(1, self.time.shape[0]) % self.segment_samples == 0
        z0 = jnp.concatenate([x0, jnp.zeros(len(GUST_STATES) + b)])
        init = (x0, jnp.zeros(len(GUST_STATES)), jnp.zeros(k), history, servo, rotor, z0)
        _, ys = jax.lax.scan(step, init, (self.inputs[:-1], states[1:], restart))
        if self.smooth:
            anchor = jnp.concatenate([jnp.zeros(gusts.stop), (_ANCHOR / self.noise_var)[:b]])
            ys = ys + restart_correction(states[1:] - ys, F, H, P, self.noise_var, anchor, self.segment_samples)
        ys = jnp.concatenate([x0[idx][None, :], ys], axis=0)
        return jax.vmap(plant.measure)(jnp.zeros((ys.shape[0], N_STATES)).at[:, idx].set(ys), self.time)

    def residuals(self, theta: Float[Array, "40"], eta: Float[Array, "E"]) -> Float[Array, " Nk"]:
        """Output errors over each channel's measured standard deviation, flattened (time-major)."""
        err = (self(theta, eta) - self.measured) / self.scale[None, :]
        return jnp.where(jnp.isfinite(err), err, 1e6).reshape(-1)

    def segment_energy(self, y: Float[Array, "*batch N k"]) -> Float[Array, "*batch S"]:
        """Normalised residual energy of each significance window (``window_samples`` long), summed over
        channels: the paired samples of the ranking's window test (its ``p_value``)."""
        err = ((y - jnp.broadcast_to(self.measured, y.shape)) / jnp.broadcast_to(self.scale, y.shape)) ** 2
        seg = np.arange(self.time.shape[0]) // self.window_samples
        onehot = jnp.asarray(np.eye(int(seg[-1]) + 1)[seg])
        return jnp.einsum("...nk,ns->...s", err, onehot)


RESTARTS: tuple[str, ...] = ("filter", "segment")
"""Where every prediction restarts: from the Kalman filter's state of the readings before the restart (``filter``),
or from that state re-estimated by least squares on the segment's own readings too (``segment``: ``smooth``,
:func:`~jaxheli.gap.segment_restart.restart_correction`)."""

RESTART = THRESHOLDS.restart
"""The diagnosis's restart (:data:`RESTARTS`; from the thresholds file, :mod:`jaxheli.gap.thresholds`): restarts from
a filter of the past alone leave errors that grow along each segment of the unstable hover model, and the re-fit of the
base bends its dynamics to shrink them (``benchmarks/yardstick_bias.py``); re-estimated from the segment, the re-fit
stays at the truth."""

SEGMENT = THRESHOLDS.segment_s
"""The diagnosis's restart interval (s; from the thresholds file): long enough that a segment's own initial state does
not absorb slow effects (a bias walk, rotor droop), short enough that the unstable hover model's runs stay near the
flight."""


def smooths(restart: str, caller: str) -> bool:
    """Whether predictions restarting as ``restart`` (:data:`RESTARTS`) re-estimate each restart from the segment
    (``make_predictor``'s ``smooth``); an unknown restart is an error naming ``caller``."""
    if restart not in RESTARTS:
        raise ValueError(f"{caller}: unknown restart {restart!r}; restarts are {RESTARTS}")
    return restart == "segment"


TRACK = 0.1
"""Default process-noise level of the restart filter, as a fraction of each channel's measurement-noise
standard deviation per sample (:func:`jaxheli.gap.kalman.gust_filter`'s ``track``)."""

TRACKS: tuple[float, ...] = (0.1, 0.3, 1.0, 3.0, 10.0)
"""Filter levels :func:`tune_track` chooses from: from trusting the model (0.1, right when the model is
close: the blind check's base model) to following the sensors (10: a restart within a few per cent of the
raw readings, right for a model far from the flight, as identified models of real flights are)."""


def noise_variance(outputs: Float[np.ndarray, "N k"]) -> Float[np.ndarray, "k"]:
    """Measurement-noise variance per channel from second differences (white noise: ``var(d2 y) = 6 var``).

    The second difference of a smooth flight signal sampled at 50-100 Hz is far below the noise, so this
    needs no model; floored at ``1e-10``.
    """
    d2 = np.diff(outputs, n=2, axis=0)
    return np.maximum(np.mean(d2**2, axis=0) / 6.0, 1e-10)


def make_predictor(
    data: FlightData | Problem, *, segment: float, g: float = G_SI, max_delay: float = 0.3,
    window: float = 0.5, track: float = TRACK, smooth: bool = False,
) -> Predictor:
    """Predictor of a record restarting every ``segment`` s from the filtered state (process noise ``track``,
    see :data:`TRACK`; ``smooth``: each restart then re-estimated from its segment's readings too,
    :func:`~jaxheli.gap.segment_restart.restart_correction`); delays up to ``max_delay`` s; residual energy in
    windows of ``window`` s (:meth:`Predictor.segment_energy`). ``data`` is a flight (all its output channels,
    gravity ``g``) or a :class:`~jaxheli.problem.Problem` (its scored channels and its ``g``)."""
    if isinstance(data, Problem):
        source, names, dt, g = str(data.source), data.outputs, data.dt, data.settings.g
        inputs, outputs, time = (np.asarray(v) for v in (data.sim.inputs, data.target, data.time))
    else:
        source, names, dt = data.source, tuple(data.output_names), data.dt
        inputs, outputs, time = data.inputs, data.outputs, data.time - data.time[0]
    n = outputs.shape[0]
    bad = [c for c in names if c in FLAPPING]
    if bad:
        raise ValueError(f"{source}: output channels {bad} are stick multiples, not states; drop them")
    seg = int(round(segment / dt))
    if seg < 2 or seg >= n:
        raise ValueError(f"{source}: segment {segment:g} s must span 2 samples to the record length "
                         f"({n} samples of {dt:g} s): choose a shorter segment")
    if not track >= 0:
        raise ValueError(f"{source}: restart filter track {track} must be >= 0")
    win = int(round(window / dt))
    if win < 1 or win >= n:
        raise ValueError(f"{source}: significance window {window} s must span 1 sample to the record length")
    std = outputs.std(axis=0)
    flat = [c for c, s in zip(names, std) if not s > 0]
    if flat:
        raise ValueError(f"{source}: measured channel(s) {flat} are constant; drop them")
    return Predictor(
        inputs=jnp.asarray(inputs),
        measured=jnp.asarray(outputs),
        time=jnp.asarray(time),
        noise_var=jnp.asarray(noise_variance(outputs)),
        scale=jnp.asarray(std),
        dt=dt,
        segment_samples=seg,
        window_samples=win,
        outputs=names,
        g=float(g),
        max_delay=float(max_delay),
        track=jnp.asarray(float(track)),
        smooth=smooth,
    )


@eqx.filter_jit
def _base_gaps(pred: Predictor, theta: Float[Array, "40"], base: Float[Array, "E"],
               tracks: Float[Array, "T"]) -> Float[Array, "T"]:
    def gap(track):
        return jnp.mean(nmse(eqx.tree_at(lambda p: p.track, pred, track)(theta, base), pred.measured))

    return jax.vmap(gap)(tracks)


def tune_track(pred: Predictor, theta: Float[Array, "40"], tracks: tuple[float, ...] = TRACKS) -> float:
    """The restart-filter level of ``tracks`` under which the base model (no effect) predicts ``pred``'s
    flight best (smallest channel-mean normalised residual energy): the filter is tuned to how far the
    model is from the flight, on the training flight only, and then held for every candidate and flight."""
    gaps = np.asarray(_base_gaps(pred, jnp.asarray(theta), jnp.asarray(no_effect(pred.outputs)),
                                 jnp.asarray(tracks, dtype=float)))
    gaps = np.where(np.isfinite(gaps), gaps, np.inf)
    return float(tracks[int(np.argmin(gaps))])
