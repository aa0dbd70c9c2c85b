"""Stage 5, velocity bias and drift against the plausible net displacement of the record
(:data:`MAX_TRAVEL_M`): the integrated velocity of a hover test stays within metres."""

from __future__ import annotations

import numpy as np

from ...data.flight import FlightData
from .._finding import Finding, skip
from .._regress import hac_lstsq
from .signals import EDGE_S, VELOCITY_CUTOFF_HZ, interior

TRAVEL_SIGMA = 2.0
"""A velocity bias or drift is significant when its displacement exceeds the plausible one by this many sigma."""

MAX_TRAVEL_M = 10.0
"""Plausible net displacement of a hover record, m: a pilot holding station ends within a few metres of the
start (or of the take-off point), so integrated velocity beyond 10 m is not a hover test but a biased or
drifting velocity channel. Records of translating flight need a larger bound (``check(max_travel=...)``)."""


def travel(flight: FlightData, max_travel: float) -> list[Finding]:
    """Bias and drift of each velocity channel, judged by the net displacement they make over the record.

    ``velocity = b + d (t - t_mid)`` (Newey-West errors). The bias moves the vehicle ``b T`` (the integrated
    velocity over the ``T`` s record); the drift alone takes it out and back by ``d T^2 / 8``. Either is
    significant when it exceeds ``max_travel`` m by more than :data:`TRAVEL_SIGMA` sigma. Not corrected: a
    real translation looks the same.
    """
    span = flight.duration
    keep = interior(flight.time, EDGE_S)
    tc = flight.time - 0.5 * (flight.time[0] + flight.time[-1])
    X = np.stack([np.ones_like(tc), tc], axis=1)[keep]
    out = []
    for vel in ("u", "v", "w"):
        if vel not in flight.output_names or np.ptp(flight.output(vel)) == 0:
            why = "the flight lacks it" if vel not in flight.output_names else "it is constant (no data)"
            out.append(skip((vel,), f"{vel} bias and drift not checked: {why}."))
            continue
        fit = hac_lstsq(flight.output(vel)[keep], X, min_bandwidth=int(1.0 / (VELOCITY_CUTOFF_HZ * flight.dt)))
        for kind, j, reach, what in (("velocity_bias", 0, span, "a net displacement"),
                                     ("velocity_drift", 1, span**2 / 8, "an excursion")):
            value, sigma = float(fit.beta[j]), float(fit.se[j])
            metres = abs(value) * reach
            unit = "m/s" if j == 0 else "m/s^2"
            out.append(Finding(kind, (vel,), value, sigma, bool(metres - max_travel > TRAVEL_SIGMA * sigma * reach),
                               f"{vel} {'mean' if j == 0 else 'drift'} {value:.3g} +- {sigma:.2g} {unit} (1 sigma): "
                               f"{what} of {metres:.3g} +- {sigma * reach:.2g} m over the {span:.3g} s record "
                               f"(plausible: {max_travel:.3g} m)."))
    return out
