"""Stage 5, velocity bias and drift against the plausible travel of the record (:data:`MAX_TRAVEL_M`): the
integrated velocity of a hover test stays within metres.

The net displacement is what the record integrates to, ``D = int v dt`` over the record less its edges. Its
uncertainty is that of the integral, not of a stationary process's mean: the sensor noise integrated,
``sigma_v dt sqrt(N)`` for white noise of level ``sigma_v`` (:func:`noise_level`: the residual above the
velocity low-pass, scaled to the whole band), and a random walk of the velocity bias, ``q sqrt(T^3 / 3)`` over
``T`` s (:data:`VELOCITY_WALK`). A pilot's slow wandering is no uncertainty of ``D``: the vehicle went where the
record integrates to, and a hover test ends within ``max_travel`` of where it began.
"""

from __future__ import annotations

import math

import numpy as np
from jaxtyping import Bool, Float

from ...data.flight import FlightData
from .._finding import Finding, skip
from .._regress import hac_lstsq
from .signals import EDGE_S, VELOCITY_CUTOFF_HZ, interior, lowpass

TRAVEL_SIGMA = 2.0
"""A velocity bias or drift is significant when its displacement exceeds the plausible one by this many sigma."""

MAX_TRAVEL_M = 10.0
"""Plausible net displacement of a hover record, m: a pilot holding station ends within a few metres of the
start (or of the take-off point), so integrated velocity beyond 10 m is not a hover test but a biased or
drifting velocity channel. Records of translating flight need a larger bound (``check(max_travel=...)``)."""

VELOCITY_WALK = 0.01
"""Random walk of a velocity channel's bias, m/s/sqrt(s): 0.1 m/s in 100 s, the accuracy of a GPS-aided
velocity estimate. Integrated over ``T`` s it moves the displacement by ``VELOCITY_WALK sqrt(T^3 / 3)`` m
(1 sigma; 3.2 m over 68 s)."""


def noise_level(v: Float[np.ndarray, "N"], fs: float, cutoff: float, keep: Bool[np.ndarray, "N"]) -> float:
    """White-noise level of ``v`` (its units): the standard deviation of ``v`` less its zero-phase low-pass at
    ``cutoff`` Hz over the ``keep`` samples, divided by ``sqrt(1 - 2 cutoff / fs)`` to count the band below
    ``cutoff`` too. Motion above ``cutoff`` counts as noise (a larger, cautious sigma); a record low-passed
    below ``cutoff`` before it was stored shows little noise."""
    residual = v - lowpass(v, cutoff, fs)
    return float(np.std(residual[keep]) / math.sqrt(1.0 - 2.0 * cutoff / fs))


def travel(flight: FlightData, max_travel: float) -> list[Finding]:
    """Bias and drift of each velocity channel, judged by the displacement they make over the record.

    ``velocity_bias``: the mean ``b`` (m/s) of ``velocity = b + d (t - t_mid)``; significant when the integral
    ``D`` (m) exceeds ``max_travel`` m by more than :data:`TRAVEL_SIGMA` times its 1-sigma (module docstring);
    the finding's uncertainty is that sigma over the span (m/s). ``velocity_drift``: ``d`` (m/s^2), which takes
    the vehicle out and back by ``d T^2 / 8`` without net displacement; judged against ``max_travel`` with its
    Newey-West error, since the data cannot tell a drift from the out-and-back wandering of a pilot, whose
    size that error measures. Neither is corrected: a real translation looks the same.
    """
    span = flight.duration
    keep = interior(flight.time, EDGE_S)
    t = flight.time[keep]
    checked = float(t[-1] - t[0])
    fs = 1.0 / flight.dt
    cutoff = min(VELOCITY_CUTOFF_HZ, 0.4 * fs)
    walk = VELOCITY_WALK * math.sqrt(checked**3 / 3.0)
    tc = flight.time - 0.5 * (flight.time[0] + flight.time[-1])
    X = np.stack([np.ones_like(tc), tc], axis=1)[keep]
    out = []
    for vel in ("u", "v", "w"):
        if vel not in flight.output_names or np.ptp(flight.output(vel)) == 0:
            why = "the flight lacks it" if vel not in flight.output_names else "it is constant (no data)"
            out.append(skip((vel,), f"{vel} bias and drift not checked: {why}."))
            continue
        v = flight.output(vel)
        fit = hac_lstsq(v[keep], X, min_bandwidth=int(1.0 / (VELOCITY_CUTOFF_HZ * flight.dt)))
        mean = float(fit.beta[0])
        displacement = float(np.trapezoid(v[keep], t))
        sigma_v = noise_level(v, fs, cutoff, keep)
        white = sigma_v * flight.dt * math.sqrt(keep.sum())
        sigma = math.hypot(white, walk)
        excess = (abs(displacement) - max_travel) / sigma
        verdict = (f", exceeded by {excess:.1f} sigma: {vel} is biased" if excess > TRAVEL_SIGMA else "")
        out.append(Finding("velocity_bias", (vel,), mean, sigma / checked, bool(excess > TRAVEL_SIGMA),
                           f"{vel} integrates to {displacement:.3g} +- {sigma:.2g} m over the {checked:.3g} s checked "
                           f"(mean {mean:.3g} m/s; 1 sigma: noise {sigma_v:.2g} m/s integrated {white:.2g} m, "
                           f"bias walk {walk:.2g} m); plausible: {max_travel:.3g} m{verdict}."))
        drift, sig_d = float(fit.beta[1]), float(fit.se[1])
        reach = span**2 / 8
        out.append(Finding("velocity_drift", (vel,), drift, sig_d,
                           bool(abs(drift) * reach - max_travel > TRAVEL_SIGMA * sig_d * reach),
                           f"{vel} drift {drift:.3g} +- {sig_d:.2g} m/s^2 (1 sigma): an excursion of "
                           f"{abs(drift) * reach:.3g} +- {sig_d * reach:.2g} m over the {span:.3g} s record "
                           f"(plausible: {max_travel:.3g} m)."))
    return out
