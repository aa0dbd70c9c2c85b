"""Undo the significant consistency findings of a flight (:func:`correct`)."""

from __future__ import annotations

import numpy as np

from ..data.flight import FlightData, FlightDataError
from ..data.preprocess import _step
from ._finding import Finding, plain
from .detectors.velocity_frame import applied_scale, frame_matrix

CORRECTED: tuple[str, ...] = ("time_scale", "rate_scale", "kinematic_lag", "rate_bias", "rate_drift",
                               "velocity_frame", "velocity_scale", "attitude_bias", "attitude_drift")
"""The kinds of finding :func:`correct` applies, in the order it applies them (the stage order of
:func:`~.consistency.check`)."""


def correct(flight: FlightData, findings: list[Finding]) -> FlightData:
    """Apply the significant findings to ``flight`` and log them in ``metadata["preprocessing"]``.

    Order (:data:`CORRECTED`, that of :func:`~.consistency.check`): time base, gyro scale, rate lag, rate bias and
    drift, velocity frame or scale, attitude bias and drift. Velocity scales are undone in sign always and in
    magnitude only where significant. Velocity lags, biases and drifts are reported, never applied: the
    rotor's flapping lag and a real translation look the same.
    """
    time, outputs = flight.time.copy(), flight.outputs.copy()
    names = flight.output_names
    applied = []

    def col(name: str) -> int:
        if name not in names:
            raise FlightDataError(f"{flight.source}: field 'outputs': a finding names channel '{name}', "
                                  f"which the flight lacks (has {names})")
        return names.index(name)

    applies = (f for f in findings if f.significant and f.kind in CORRECTED)
    for f in sorted(applies, key=lambda f: CORRECTED.index(f.kind)):
        kind, est = f.kind, f.estimate
        if kind == "time_scale":
            time = time[0] + (time - time[0]) / est
        elif kind == "rate_scale":
            outputs[:, col(f.channels[0])] /= est
        elif kind == "velocity_scale":
            outputs[:, col(f.channels[0])] /= applied_scale(est, f.uncertainty)
        elif kind == "kinematic_lag":
            c = col(f.channels[0])
            outputs[:, c] = np.interp(time + est, time, outputs[:, c])
        elif kind in ("rate_bias", "attitude_bias"):
            outputs[:, col(f.channels[0])] -= est
        elif kind in ("rate_drift", "attitude_drift"):
            outputs[:, col(f.channels[0])] -= est * (time - 0.5 * (time[0] + time[-1]))
        elif kind == "velocity_frame":
            cols = [col(c) for c in f.channels]
            outputs[:, cols] = outputs[:, cols] @ np.linalg.inv(frame_matrix(est, f.uncertainty, f.channels)).T
        applied.append({"kind": kind, "channels": list(f.channels), "estimate": plain(est)})
    record = {"step": "consistency.correct", "applied": applied}
    return _step(flight, record, time=time, outputs=outputs)
