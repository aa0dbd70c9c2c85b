"""Is the flight data itself consistent? Flight-test data compatibility checks before blaming the model.

Five stages, each run on the record corrected by the stages before it (as :func:`correct` applies them), each
a module of :mod:`.detectors`:

1. **Kinematics** (:mod:`.detectors.kinematics`): angles against body rates, per axis roll and pitch: the
   time-scale factor, the rate's lag, scale, bias and drift.
2. **Velocity frame** (:mod:`.detectors.velocity_frame`): velocities against attitude, near hover
   ``u' = -g theta + ...`` and ``v' = g phi + ...``: a rotation about z and a signed scale per channel.
3. **Attitude bias and drift** from the same regression's constant and time terms.
4. **Velocity lags** (:mod:`.detectors.velocity_lags`): each body velocity against its attitude-driven
   acceleration; reported, not corrected.
5. **Velocity bias and drift** (:mod:`.detectors.travel`) against the plausible net displacement of the
   record (:data:`MAX_TRAVEL_M`): the integrated velocity of a hover test stays within metres.

Every estimate carries a **1-sigma** uncertainty: Newey-West (autocorrelation-consistent) regression
standard errors, propagated to ratios by the delta method; a velocity bias that of the record's integral
(sensor noise integrated, a bias random walk). A finding is ``significant`` when it differs
from its nominal value by more than ``3 sigma`` *and* by more than a practical tolerance
(:data:`~._finding.TOLERANCE`), so long records do not flag harmless deviations. Every lag is reported; it is
significant beyond :data:`~._finding.LAG_SIGMA` sigma and at least one sample. The yaw rate's pair is reported
as ``not_checked``: the measurable channels carry no heading angle. :func:`correct` undoes the significant
findings; :func:`write_check` writes them with a plot.
"""

from __future__ import annotations

from ..data.flight import FlightData
from ._finding import Finding as Finding, skip
from .check_output import plot_kinematics as plot_kinematics, write_check as write_check
from .correction import correct as correct
from .detectors.kinematics import axis_findings, kinematic_fits, time_scale
from .detectors.signals import EDGE_S, MIN_DURATION_S
from .detectors.travel import MAX_TRAVEL_M as MAX_TRAVEL_M, travel
from .detectors.velocity_frame import attitude_bias, velocity_frame
from .detectors.velocity_lags import velocity_lags


def check(flight: FlightData, max_travel: float = MAX_TRAVEL_M) -> list[Finding]:
    """Data-compatibility findings of ``flight`` (kinematics, velocity frame, attitude bias, velocity lags,
    velocity bias and drift against ``max_travel`` m of net displacement), in stage order.

    Checks whose channels are missing, constant or too short are reported as ``not_checked`` findings.
    """
    if flight.duration - 2 * EDGE_S < MIN_DURATION_S:
        return [skip(flight.output_names, f"the record lasts {flight.duration:.3g} s; the checks need at "
                                          f"least {MIN_DURATION_S + 2 * EDGE_S:.3g} s")]
    findings, fits = time_scale(flight)
    current = correct(flight, findings)
    if findings[0].significant:
        fits, _ = kinematic_fits(current)
    findings += axis_findings(fits, current)
    if "r" in flight.output_names:
        findings.append(skip(("r", "psi"), "r against dpsi/dt not checked: the flight carries no heading angle."))
    current = correct(flight, findings)
    findings += velocity_frame(current)
    findings += attitude_bias(correct(flight, findings))
    current = correct(flight, findings)
    findings += velocity_lags(current)
    findings += travel(current, max_travel)
    return findings
