"""One data-consistency result (:class:`Finding`) and when an estimate is significant."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

N_SIGMA = 3.0
"""Significance: estimate further than this many standard deviations from its nominal value..."""

TOLERANCE: dict[str, float] = {
    "time_scale": 0.02, "rate_scale": 0.03, "rate_bias": 0.005, "rate_drift": 0.005,
    "velocity_rotation": math.radians(3.0), "velocity_scale": 0.25, "attitude_bias": 0.01, "attitude_drift": 0.01,
}
"""...and further than this: scale factors (fraction), rate bias rad/s, velocity rotation rad,
attitude bias rad. Drifts are judged by the change they make over the record (rad/s, rad)."""

LAG_SIGMA = 2.0
"""A lag (rate or velocity channel) is significant beyond this many sigma and at least one sample."""


@dataclasses.dataclass(frozen=True)
class Finding:
    """One data-consistency result.

    ``estimate`` and ``uncertainty`` (1 sigma, same shape: a float or a ``{name: float}`` dict) are in SI
    units (s, rad, rad/s, rad/s^2, m/s, m/s^2, scale factors dimensionless); ``significant`` says whether
    the data need correcting (velocity lags, biases and drifts: need a look, :func:`~.correction.correct` leaves them);
    ``message`` is one plain sentence with the numbers.
    """

    kind: str
    channels: tuple[str, ...]
    estimate: float | dict[str, float]
    uncertainty: float | dict[str, float]
    significant: bool
    message: str

    def to_json(self) -> dict[str, Any]:
        """Plain JSON-ready dict with exactly the keys kind, channels, estimate, uncertainty, significant, message."""
        return {"kind": self.kind, "channels": list(self.channels), "estimate": plain(self.estimate),
                "uncertainty": plain(self.uncertainty), "significant": bool(self.significant),
                "message": self.message}


def beyond(deviation: float, sigma: float, kind: str) -> bool:
    """Significant: more than ``N_SIGMA`` sigma and more than the practical tolerance of ``kind``."""
    return bool(np.isfinite(deviation) and np.isfinite(sigma) and abs(deviation) > N_SIGMA * sigma
                and abs(deviation) > TOLERANCE[kind])


def lag_beyond(tau: float, sigma: float, dt: float) -> bool:
    """Significant lag: beyond :data:`LAG_SIGMA` sigma and at least one sample ``dt`` (s)."""
    return bool(np.isfinite(tau) and np.isfinite(sigma) and abs(tau) > LAG_SIGMA * sigma and abs(tau) >= dt)


def skip(channels: tuple[str, ...], message: str) -> Finding:
    """A ``not_checked`` finding of ``channels`` saying why."""
    return Finding("not_checked", tuple(channels), {}, {}, False, message)


def plain(value: Any) -> Any:
    """JSON-ready floats (``None`` where not finite), kept in a dict where given one."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return float(value) if np.isfinite(value) else None
