"""Is the flight data itself consistent? Flight-test data compatibility checks before blaming the model.

Five stages, each run on the record corrected by the stages before it (as :func:`correct` applies them):

1. **Kinematics** (angles against body rates, per axis roll and pitch). The full Euler relations
   ``phi' = p + (q sin phi + r cos phi) tan theta`` and ``theta' = q cos phi - r sin phi`` are fitted as
   ``angle' = s (c rate(t + tau) + e - c b - c d (t - t_mid))`` on low-passed signals, with ``c`` the
   rate's coefficient and ``e`` the cross-axis terms. Estimates: the time-scale factor ``k = 1 / s``
   (recorded time / true time; all axes agree when the time base is off, one axis alone means a gyro
   scale error), the lag ``tau`` (s, > 0 when the rate channel lags the angle; :func:`~._lag.fit_lag`:
   a whole-sample grid, a parabola, then Gauss-Newton on a fractional shift), the rate bias ``b`` (rad/s)
   and its drift ``d`` (rad/s^2).
2. **Velocity frame** (velocities against attitude): near hover ``u' = -g theta + ...`` and
   ``v' = g phi + ...``. Each velocity derivative is regressed on the attitude angles, the velocities
   (speed derivatives), the body rates and the centred sticks (rotor flapping, quasi-steady), a constant
   and time; the attitude columns give the 2 x 2 map ``T`` from true to recorded velocities, split into a
   rotation ``alpha`` (rad) and a signed scale per channel (-1: sign flipped).
3. **Attitude bias and drift** from the same regression's constant and time terms: the roll / pitch
   offset (rad) at which the helicopter would not accelerate, and its drift (rad/s). A velocity drift
   looks the same (``g`` times the offset, m/s^2); the two cannot be told apart from these channels.
4. **Velocity lags**: each body velocity ``u, v, w`` against its kinematic acceleration, gravity and the
   rate cross terms of ``V' = F/m - omega x V + g`` (``u' = r v - q w - g sin theta + X``, ...), with a
   scale, a drag term, the collective for ``w``, a constant and time standing in for the unmeasured force.
   The lag includes the rotor's own lag behind the fuselage (its flapping time constant) where the force
   model misses it, and ``w``'s is weak unless the attitude varies: its uncertainty says so. A lag is
   significant only where the pair is identified (the acceleration's gain beyond 3 sigma of zero), and
   not corrected: a lagging sensor and the rotor's own lag look the same here.
5. **Velocity bias and drift** against the plausible net displacement of the record
   (:data:`MAX_TRAVEL_M`): the integrated velocity of a hover test stays within metres.

Every estimate carries a **1-sigma** uncertainty: Newey-West (autocorrelation-consistent) regression
standard errors, propagated to ratios by the delta method. A finding is ``significant`` when it differs
from its nominal value by more than ``3 sigma`` *and* by more than a practical tolerance
(:data:`TOLERANCE`), so long records do not flag harmless deviations. Every lag is reported; it is
significant beyond :data:`LAG_SIGMA` sigma and at least one sample. The yaw rate's pair is reported as
``not_checked``: the measurable channels carry no heading angle.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import scipy.signal
import scipy.stats
from jaxtyping import Float

from ..data.flight import FlightData, FlightDataError
from ..model import G_SI, INPUT_NAMES
from ..data.preprocess import _step
from ._lag import fit_lag
from ._regress import Fit, hac_lstsq, well_posed

N_SIGMA = 3.0
"""Significance: estimate further than this many standard deviations from its nominal value..."""

TOLERANCE: dict[str, float] = {
    "time_scale": 0.02, "rate_scale": 0.03, "rate_bias": 0.005, "rate_drift": 0.005,
    "velocity_rotation": math.radians(3.0), "velocity_scale": 0.25, "attitude_bias": 0.01, "attitude_drift": 0.01,
}
"""...and further than this: scale factors (fraction), rate bias rad/s, velocity rotation rad,
attitude bias rad. Drifts are judged by the change they make over the record (rad/s, rad)."""

KINEMATIC_CUTOFF_HZ = 5.0
"""Low-pass (zero-phase Butterworth, order 4) applied before the kinematic regression; above it gyros
carry rotor vibration (data README fact 2)."""

VELOCITY_CUTOFF_HZ = 2.0
"""Low-pass before the velocity regression (GPS velocities are smooth; the flapping model is quasi-steady)."""

EDGE_S = 0.5
"""Seconds dropped at each end of a regression (filter transients, shifted samples, resampling ringing)."""

MAX_LAG_S = 0.4
"""Largest kinematic lag searched, s."""

MIN_DURATION_S = 2.0
"""Shortest record (after the edges) a check runs on, s."""

LAG_SIGMA = 2.0
"""A lag (rate or velocity channel) is significant beyond this many sigma and at least one sample."""

TRAVEL_SIGMA = 2.0
"""A velocity bias or drift is significant when its displacement exceeds the plausible one by this many sigma."""

MAX_TRAVEL_M = 10.0
"""Plausible net displacement of a hover record, m: a pilot holding station ends within a few metres of the
start (or of the take-off point), so integrated velocity beyond 10 m is not a hover test but a biased or
drifting velocity channel. Records of translating flight need a larger bound (``check(max_travel=...)``)."""

_ORDER = ("time_scale", "rate_scale", "kinematic_lag", "rate_bias", "rate_drift", "velocity_frame", "velocity_scale",
          "attitude_bias", "attitude_drift")
"""The order in which :func:`correct` applies findings (the stage order of :func:`check`)."""

_AXES = (("roll", "phi", "p"), ("pitch", "theta", "q"))
_VELOCITIES = (("u", "theta", -1.0), ("v", "phi", 1.0))
"""Velocity, its attitude partner and the sign of ``g`` in ``velocity' = sign g angle``."""
_SPEEDS = (("u", ("theta",)), ("v", ("phi",)), ("w", ("phi", "theta")))
"""Body velocity and the Euler angles its gravity component needs."""


@dataclasses.dataclass(frozen=True)
class Finding:
    """One data-consistency result.

    ``estimate`` and ``uncertainty`` (1 sigma, same shape: a float or a ``{name: float}`` dict) are in SI
    units (s, rad, rad/s, rad/s^2, m/s, m/s^2, scale factors dimensionless); ``significant`` says whether
    the data need correcting (velocity lags, biases and drifts: need a look, :func:`correct` leaves them);
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
        return {"kind": self.kind, "channels": list(self.channels), "estimate": _plain(self.estimate),
                "uncertainty": _plain(self.uncertainty), "significant": bool(self.significant),
                "message": self.message}


def check(flight: FlightData, max_travel: float = MAX_TRAVEL_M) -> list[Finding]:
    """Data-compatibility findings of ``flight`` (kinematics, velocity frame, attitude bias, velocity lags,
    velocity bias and drift against ``max_travel`` m of net displacement), in stage order.

    Checks whose channels are missing, constant or too short are reported as ``not_checked`` findings.
    """
    if flight.duration - 2 * EDGE_S < MIN_DURATION_S:
        return [_skip(flight.output_names, f"the record lasts {flight.duration:.3g} s; the checks need at "
                                           f"least {MIN_DURATION_S + 2 * EDGE_S:.3g} s")]
    findings, fits = _time_scale(flight)
    current = correct(flight, findings)
    if findings[0].significant:
        fits, _ = _kinematic_fits(current)
    findings += _axis_findings(fits, current)
    if "r" in flight.output_names:
        findings.append(_skip(("r", "psi"), "r against dpsi/dt not checked: the flight carries no heading angle."))
    current = correct(flight, findings)
    findings += _velocity_frame(current)
    findings += _attitude_bias(correct(flight, findings))
    current = correct(flight, findings)
    findings += _velocity_lags(current)
    findings += _travel(current, max_travel)
    return findings


def correct(flight: FlightData, findings: list[Finding]) -> FlightData:
    """Apply the significant findings to ``flight`` and log them in ``metadata["preprocessing"]``.

    Order (:data:`_ORDER`, that of :func:`check`): time base, gyro scale, rate lag, rate bias and drift,
    velocity frame or scale, attitude bias and drift. Velocity scales are undone in sign always and in
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

    for f in sorted((f for f in findings if f.significant and f.kind in _ORDER), key=lambda f: _ORDER.index(f.kind)):
        kind, est = f.kind, f.estimate
        if kind == "time_scale":
            time = time[0] + (time - time[0]) / est
        elif kind == "rate_scale":
            outputs[:, col(f.channels[0])] /= est
        elif kind == "velocity_scale":
            outputs[:, col(f.channels[0])] /= _applied_scale(est, f.uncertainty)
        elif kind == "kinematic_lag":
            c = col(f.channels[0])
            outputs[:, c] = np.interp(time + est, time, outputs[:, c])
        elif kind in ("rate_bias", "attitude_bias"):
            outputs[:, col(f.channels[0])] -= est
        elif kind in ("rate_drift", "attitude_drift"):
            outputs[:, col(f.channels[0])] -= est * (time - 0.5 * (time[0] + time[-1]))
        elif kind == "velocity_frame":
            cols = [col(c) for c in f.channels]
            outputs[:, cols] = outputs[:, cols] @ np.linalg.inv(_frame_matrix(est, f.uncertainty, f.channels)).T
        applied.append({"kind": kind, "channels": list(f.channels), "estimate": _plain(est)})
    record = {"step": "consistency.correct", "applied": applied}
    return _step(flight, record, time=time, outputs=outputs)


# ---- stage 1: kinematics ------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _AxisFit:
    """Kinematic fit of one axis: scale ``s``, lag ``tau`` (s), rate bias ``b`` and drift ``d`` with sigmas."""

    axis: str
    angle: str
    rate: str
    values: dict[str, float]
    sigmas: dict[str, float]
    converged: bool


def _time_scale(flight: FlightData) -> tuple[list[Finding], list[_AxisFit]]:
    """The common time-scale factor of all checkable axes (first finding) and the per-axis fits."""
    fits, skipped = _kinematic_fits(flight)
    if not fits:
        return [_skip(("time",), "Time base not checked: no axis has both an Euler angle and a varying body "
                                 "rate."), *skipped], fits
    k = np.array([1.0 / f.values["s"] for f in fits])
    sk = np.array([f.sigmas["s"] / f.values["s"] ** 2 for f in fits])
    w = 1.0 / sk**2
    common, sigma = float(np.sum(w * k) / np.sum(w)), float(1.0 / np.sqrt(np.sum(w)))
    chi2 = float(np.sum(w * (k - common) ** 2))
    agree = len(fits) == 1 or scipy.stats.chi2.sf(chi2, len(fits) - 1) > 1e-3
    per_axis = ", ".join(f"{f.axis} {ki:.4f} +- {si:.4f}" for f, ki, si in zip(fits, k, sk))
    significant = agree and _beyond(common - 1.0, sigma, "time_scale")
    note = ("the axes agree" if agree else "the axes disagree, so it is a gyro scale error, not the time base")
    message = (f"Time-scale factor (recorded / true time) {common:.4f} +- {sigma:.4f} (1 sigma; {per_axis}); "
               f"{note}.")
    return [Finding("time_scale", ("time",), common, sigma, significant, message), *skipped], fits


def _kinematic_fits(flight: FlightData) -> tuple[list[_AxisFit], list[Finding]]:
    """Fit every roll / pitch axis whose angle and rate are present and not constant; ``not_checked``
    findings (with the reason) for the others."""
    cutoff, terms = _kinematic_terms(flight)
    fits, skipped = [], []
    for axis, angle, rate in _AXES:
        key = (axis, angle, rate)
        fit = _fit_axis(flight.time, *terms[key], flight.dt, cutoff) if key in terms else None
        if fit is not None:
            fits.append(_AxisFit(axis, angle, rate, *fit))
            continue
        why = (f"the flight lacks {angle if angle not in flight.output_names else rate}"
               if not {angle, rate} <= set(flight.output_names) else
               f"{rate} is constant (no data)" if np.ptp(flight.output(rate)) == 0 else
               "the regressors are collinear")
        skipped.append(_skip((rate, angle), f"{rate} against d{angle}/dt (lag, scale, bias) not checked: {why}."))
    return fits, skipped


def _kinematic_terms(flight: FlightData) -> tuple[float, dict[tuple[str, str, str], tuple[np.ndarray, ...]]]:
    """Low-pass cutoff (Hz) and, per checkable axis, the filtered angle, rate, rate coefficient ``c`` and
    cross-axis term ``e`` of the Euler relation ``angle' = c rate + e`` (missing rates count as zero)."""
    names = flight.output_names
    fs = 1.0 / flight.dt
    cutoff = min(KINEMATIC_CUTOFF_HZ, 0.4 * fs)
    if flight.duration - 2 * EDGE_S < MIN_DURATION_S:
        return cutoff, {}
    sig = _signals(flight, cutoff)
    zero = np.zeros(flight.n_samples)
    phi, theta, q, r = (sig.get(n, zero) for n in ("phi", "theta", "q", "r"))
    couple = {"roll": (np.ones_like(phi), (q * np.sin(phi) + r * np.cos(phi)) * np.tan(theta)),
              "pitch": (np.cos(phi), -r * np.sin(phi))}
    return cutoff, {(axis, angle, rate): (sig[angle], sig[rate], *couple[axis]) for axis, angle, rate in _AXES
                    if {angle, rate} <= set(names) and np.ptp(flight.output(rate)) > 0}


def _fit_axis(
    t: Float[np.ndarray, "N"], angle: np.ndarray, rate: np.ndarray, c: np.ndarray, e: np.ndarray, dt: float,
    cutoff: float,
) -> tuple[dict[str, float], dict[str, float], bool] | None:
    """Lag by :func:`~._lag.fit_lag`, least squares for the rest:
    ``angle' = s (c rate(t + tau) + e - c b - c d t')``."""
    tc = t - 0.5 * (t[0] + t[-1])
    lag = fit_lag(t, np.gradient(angle, dt), rate, [c, c * tc], max_lag=MAX_LAG_S, edge=EDGE_S,
                  bandwidth=int(1.0 / (cutoff * dt)), weight=c, offset=e)
    if lag is None:
        return None
    fit = lag.fit
    b, sig_b = _ratio(fit, 2, -1.0)
    d, sig_d = _ratio(fit, 3, -1.0)
    values = {"s": float(fit.beta[0]), "tau": lag.tau, "b": b, "d": d}
    sigmas = {"s": float(fit.se[0]), "tau": lag.sigma, "b": sig_b, "d": sig_d}
    return values, sigmas, lag.converged


def _axis_findings(fits: list[_AxisFit], flight: FlightData) -> list[Finding]:
    """Gyro scale, lag, bias and drift findings of each fitted axis (on the time-corrected record)."""
    out = []
    span = flight.duration
    for f in fits:
        v, sg = f.values, f.sigmas
        g_scale = 1.0 / v["s"]
        sig_g = sg["s"] / v["s"] ** 2
        out.append(Finding("rate_scale", (f.rate,), g_scale, sig_g, _beyond(g_scale - 1, sig_g, "rate_scale"),
                           f"{f.rate} reads {g_scale:.4f} +- {sig_g:.4f} (1 sigma) times the rate implied by "
                           f"d{f.angle}/dt."))
        lag_ok = f.converged and _lag_beyond(v["tau"], sg["tau"], flight.dt)
        out.append(Finding("kinematic_lag", (f.rate, f.angle), v["tau"], sg["tau"], lag_ok,
                           f"{f.rate} lags {f.angle} by {1e3 * v['tau']:.1f} +- {1e3 * sg['tau']:.1f} ms (1 sigma)"
                           + ("." if f.converged else "; the lag search did not converge or reached its limit.")))
        out.append(Finding("rate_bias", (f.rate,), v["b"], sg["b"], _beyond(v["b"], sg["b"], "rate_bias"),
                           f"{f.rate} has a bias of {v['b']:.4f} +- {sg['b']:.4f} rad/s (1 sigma) against "
                           f"d{f.angle}/dt."))
        out.append(Finding("rate_drift", (f.rate,), v["d"], sg["d"],
                           _beyond(v["d"] * span, sg["d"] * span, "rate_drift"),
                           f"{f.rate} bias drifts by {v['d']:.2e} +- {sg['d']:.2e} rad/s^2 (1 sigma), "
                           f"{v['d'] * span:.4f} rad/s over the {span:.3g} s record."))
    return out


# ---- stages 2 and 3: velocities against attitude -------------------------------------------------------------


def _velocity_fits(flight: FlightData) -> tuple[list[tuple[str, str, float]], list[Fit], list[Finding]]:
    """Regress each velocity derivative on attitude, velocities, rates, centred sticks, 1 and time."""
    names = flight.output_names
    pairs, skipped = [], []
    for vel, angle, sign in _VELOCITIES:
        if not {vel, angle} <= set(names):
            skipped.append(_skip((vel, angle), f"{vel} against {angle} not checked: the flight lacks "
                                               f"{vel if vel not in names else angle}."))
        elif np.ptp(flight.output(vel)) == 0 or np.ptp(flight.output(angle)) == 0:
            skipped.append(_skip((vel, angle), f"{vel} against {angle} not checked: a channel is constant "
                                               "(no data)."))
        else:
            pairs.append((vel, angle, sign))
    if not pairs:
        return pairs, [], skipped
    fs = 1.0 / flight.dt
    cutoff = min(VELOCITY_CUTOFF_HZ, 0.4 * fs)
    sticks = _lowpass(flight.inputs - flight.inputs.mean(axis=0), cutoff, fs)
    sig = _signals(flight, cutoff)
    tc = flight.time - 0.5 * (flight.time[0] + flight.time[-1])
    nuisance = [sig[n] for n in ("p", "q") if n in sig and np.ptp(sig[n]) > 0]
    nuisance += [sticks[:, j] for j in range(len(INPUT_NAMES)) if np.ptp(flight.inputs[:, j]) > 0]
    nuisance += [np.gradient(x, flight.dt) for x in nuisance]
    X = np.stack([sig[a] for _, a, _ in pairs] + [sig[v] for v, _, _ in pairs] + nuisance
                 + [np.ones_like(tc), tc], axis=1)
    keep = _interior(flight.time, EDGE_S)
    if not well_posed(X[keep]):
        return [], [], skipped + [_skip(tuple(v for v, _, _ in pairs),
                                        "velocity checks not possible: the regressors are collinear.")]
    fits = [hac_lstsq(np.gradient(sig[v], flight.dt)[keep], X[keep], min_bandwidth=int(1.0 / (cutoff * flight.dt)))
            for v, _, _ in pairs]
    return pairs, fits, skipped


def _velocity_frame(flight: FlightData) -> list[Finding]:
    """Rotation and signed scale of the velocity channels, from the attitude block of the regression."""
    pairs, fits, out = _velocity_fits(flight)
    if not pairs:
        return out
    g = float(flight.metadata.get("g", G_SI))
    m = len(pairs)
    gain = np.array([[fit.beta[j] / (pairs[j][2] * g) for j in range(m)] for fit in fits])
    sd = np.array([[fit.se[j] / g for j in range(m)] for fit in fits])
    if m == 1:
        (vel, angle, _), s, sigma = pairs[0], float(gain[0, 0]), float(sd[0, 0])
        return out + [Finding("velocity_scale", (vel,), s, sigma, _beyond(s - 1.0, sigma, "velocity_scale"),
                              f"{vel} {_flip(s, sigma)}a scale of {s:.3f} +- {sigma:.3f} (1 sigma) against g {angle}.")]
    alpha, sig_alpha, scales, sig_scales = _split_frame(gain, sd)
    vels = tuple(v for v, _, _ in pairs)
    est = {"rotation": alpha, **{f"scale_{v}": s for v, s in zip(vels, scales)}}
    unc = {"rotation": sig_alpha, **{f"scale_{v}": s for v, s in zip(vels, sig_scales)}}
    parts = _frame_parts(est, unc)
    scale_text = ", ".join(f"{v} {_flip(s, ss)}scale {s:.3f} +- {ss:.3f}" for v, s, ss in zip(vels, scales, sig_scales))
    return out + [Finding("velocity_frame", vels, est, unc, any(parts.values()),
                          f"The velocity axes are rotated by {math.degrees(alpha):.2f} +- {math.degrees(sig_alpha):.2f} "
                          f"deg about z from the attitude-implied body axes; {scale_text} (1 sigma).")]


def _frame_parts(est: dict[str, float], unc: dict[str, float]) -> dict[str, bool]:
    """Which parts of a ``velocity_frame`` estimate are significant."""
    return {k: _beyond(est[k] - (k != "rotation"), unc[k], "velocity_rotation" if k == "rotation" else "velocity_scale")
            for k in est}


def _flip(s: float, sigma: float) -> str:
    return "is sign-flipped, " if s < 0 and abs(s) > N_SIGMA * sigma else ""


def _split_frame(
    gain: Float[np.ndarray, "2 2"], sd: Float[np.ndarray, "2 2"]
) -> tuple[float, float, list[float], list[float]]:
    """``gain = R(alpha) diag(s_u, s_v)``: rotation (rad, |alpha| <= 90 deg) and signed scales, with sigmas."""
    angles, sig_angles, scales, sig_scales = [], [], [], []
    for x, y, sx, sy in ((gain[0, 0], gain[1, 0], sd[0, 0], sd[1, 0]), (gain[1, 1], -gain[0, 1], sd[1, 1], sd[0, 1])):
        r2 = x * x + y * y
        a = math.atan2(y, x)
        sign = 1.0
        if abs(a) > math.pi / 2:
            a, sign = a - math.copysign(math.pi, a), -1.0
        angles.append(a)
        sig_angles.append(math.sqrt((y * y * sx * sx + x * x * sy * sy) / r2) / math.sqrt(r2))
        scales.append(sign * math.sqrt(r2))
        sig_scales.append(math.sqrt((x * x * sx * sx + y * y * sy * sy) / r2))
    w = 1.0 / np.square(sig_angles)
    alpha = float(np.sum(w * np.array(angles)) / np.sum(w))
    return alpha, float(1.0 / np.sqrt(np.sum(w))), scales, sig_scales


def _attitude_bias(flight: FlightData) -> list[Finding]:
    """Attitude offsets and drifts from the constant and time terms of the velocity regression."""
    pairs, fits, _ = _velocity_fits(flight)
    out = []
    span = flight.duration
    for j, ((vel, angle, _), fit) in enumerate(zip(pairs, fits)):
        bias, sig_b = _ratio(fit, -2, -1.0, j)
        drift, sig_d = _ratio(fit, -1, -1.0, j)
        g = abs(fit.beta[j])
        out.append(Finding("attitude_bias", (angle,), bias, sig_b, _beyond(bias, sig_b, "attitude_bias"),
                           f"{angle} is offset by {bias:.4f} +- {sig_b:.4f} rad (1 sigma) from the attitude at which "
                           f"{vel} would not accelerate (or {vel} drifts by {g * bias:.3f} m/s^2)."))
        out.append(Finding("attitude_drift", (angle,), drift, sig_d,
                           _beyond(drift * span, sig_d * span, "attitude_drift"),
                           f"{angle} drifts by {drift:.2e} +- {sig_d:.2e} rad/s (1 sigma), {drift * span:.4f} rad "
                           f"over the {span:.3g} s record."))
    return out


# ---- stages 4 and 5: velocity lags against the attitude-driven acceleration; velocity bias and drift ----------


def _velocity_lags(flight: FlightData) -> list[Finding]:
    """Lag of each body velocity against its kinematic acceleration (:func:`_speed_terms`), by
    :func:`~._lag.fit_lag` with a scale, a drag term (the velocity itself), the collective for ``w``, a
    constant and time as nuisance; > 0 when the velocity channel lags."""
    names = flight.output_names
    fs = 1.0 / flight.dt
    cutoff = min(VELOCITY_CUTOFF_HZ, 0.4 * fs)
    sig = _signals(flight, cutoff)
    col = _lowpass(flight.inputs[:, INPUT_NAMES.index("col")] - flight.inputs[:, INPUT_NAMES.index("col")].mean(),
                   cutoff, fs)
    tc = flight.time - 0.5 * (flight.time[0] + flight.time[-1])
    g = float(flight.metadata.get("g", G_SI))
    out = []
    for vel, angles in _SPEEDS:
        channels = (vel, *angles)
        why = (f"the flight lacks {vel}" if vel not in names else
               f"the flight lacks {' and '.join(angles)}" if not any(a in names for a in angles) else
               f"{vel} is constant (no data)" if np.ptp(flight.output(vel)) == 0 else "")
        if why:
            out.append(_skip(channels, f"{vel} lag not checked: {why}."))
            continue
        fixed = [np.ones_like(tc), tc, sig[vel]] + ([col] if vel == "w" and np.ptp(col) > 0 else [])
        lag = fit_lag(flight.time, np.gradient(sig[vel], flight.dt), _speed_terms(sig, g)[vel], fixed,
                      max_lag=MAX_LAG_S, edge=EDGE_S, bandwidth=int(1.0 / (cutoff * flight.dt)))
        if lag is None:
            out.append(_skip(channels, f"{vel} lag not checked: the regressors are collinear."))
            continue
        tau, sigma = -lag.tau, lag.sigma
        gain, sig_gain = float(lag.fit.beta[0]), float(lag.fit.se[0])
        identified = abs(gain) > N_SIGMA * sig_gain
        note = (f"; the pair is not identified (gain within {N_SIGMA:g} sigma of 0)" if not identified else
                "; the lag search did not converge or reached its limit" if not lag.converged else "")
        out.append(Finding("velocity_lag", channels, tau, sigma,
                           identified and lag.converged and _lag_beyond(tau, sigma, flight.dt),
                           f"{vel} lags its attitude-driven acceleration by {1e3 * tau:.1f} +- {1e3 * sigma:.1f} ms "
                           f"(1 sigma; gain {gain:.2f} +- {sig_gain:.2f}){note}."))
    return out


def _speed_terms(sig: dict[str, np.ndarray], g: float) -> dict[str, np.ndarray]:
    """Body-axis kinematic accelerations (m/s^2): gravity and the rate cross terms of ``V' = F/m - w x V + g``
    (missing channels count as zero)."""
    zero = np.zeros_like(next(iter(sig.values())))
    u, v, w, p, q, r, phi, theta = (sig.get(n, zero) for n in ("u", "v", "w", "p", "q", "r", "phi", "theta"))
    return {"u": r * v - q * w - g * np.sin(theta),
            "v": p * w - r * u + g * np.sin(phi) * np.cos(theta),
            "w": q * u - p * v + g * np.cos(phi) * np.cos(theta)}


def _travel(flight: FlightData, max_travel: float) -> list[Finding]:
    """Bias and drift of each velocity channel, judged by the net displacement they make over the record.

    ``velocity = b + d (t - t_mid)`` (Newey-West errors). The bias moves the vehicle ``b T`` (the integrated
    velocity over the ``T`` s record); the drift alone takes it out and back by ``d T^2 / 8``. Either is
    significant when it exceeds ``max_travel`` m by more than :data:`TRAVEL_SIGMA` sigma. Not corrected: a
    real translation looks the same.
    """
    span = flight.duration
    keep = _interior(flight.time, EDGE_S)
    tc = flight.time - 0.5 * (flight.time[0] + flight.time[-1])
    X = np.stack([np.ones_like(tc), tc], axis=1)[keep]
    out = []
    for vel, _ in _SPEEDS:
        if vel not in flight.output_names or np.ptp(flight.output(vel)) == 0:
            why = "the flight lacks it" if vel not in flight.output_names else "it is constant (no data)"
            out.append(_skip((vel,), f"{vel} bias and drift not checked: {why}."))
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


def _frame_matrix(est: dict[str, float], unc: dict[str, float], vels: tuple[str, ...]) -> Float[np.ndarray, "2 2"]:
    """``R(rotation) diag(scale_u, scale_v)`` of the significant parts of a ``velocity_frame`` estimate."""
    parts = _frame_parts(est, unc)
    a = est["rotation"] if parts["rotation"] else 0.0
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return rot @ np.diag([_applied_scale(est[f"scale_{v}"], unc[f"scale_{v}"]) if parts[f"scale_{v}"] else 1.0
                          for v in vels])


def _applied_scale(s: float, sigma: float) -> float:
    """The velocity scale ``correct`` divides by: the sign always, the magnitude only where it differs from 1
    significantly."""
    return math.copysign(abs(s) if _beyond(abs(s) - 1.0, sigma, "velocity_scale") else 1.0, s)


# ---- report --------------------------------------------------------------------------------------------------


def plot_kinematics(flight: FlightData, corrected: FlightData, path: str | Path) -> Path:
    """PNG of the kinematic comparison per axis: d(angle)/dt against the rate-implied ``c rate + e``, before
    and after :func:`correct` (signals low-passed as in the check)."""
    from ..plots import _save, _subplots

    columns = (("recorded", flight), ("corrected", corrected))
    terms = [_kinematic_terms(f)[1] for _, f in columns]
    keys = list(terms[0]) or [("none", "-", "-")]
    fig, axes = _subplots(len(keys), 2, figsize=(13, 2.4 * len(keys) + 0.6), sharex="col", squeeze=False)
    for row, key in enumerate(keys):
        for (label, f), term, ax in zip(columns, terms, axes[row]):
            if key in term:
                ang, rate, c, e = term[key]
                ax.plot(f.time, np.gradient(ang, f.dt), color="black", lw=0.9, label=f"d{key[1]}/dt")
                ax.plot(f.time, c * rate + e, lw=0.8, label=f"from {key[2]} (Euler kinematics)")
                ax.legend(loc="upper right", fontsize=8, ncol=2)
            ax.set_title(f"{key[0]}, {label}", fontsize=9)
            ax.set_ylabel("rad/s")
            ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("time [s]")
    fig.suptitle(f"Kinematic consistency: {flight.source}", fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def write_check(flight: FlightData, findings: list[Finding], out: str | Path) -> list[Path]:
    """Write ``consistency.json`` (the findings' :meth:`Finding.to_json`) and ``consistency.png``
    (:func:`plot_kinematics` of ``flight`` before and after :func:`correct`) into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "consistency.json"
    path.write_text(json.dumps([f.to_json() for f in findings], indent=2))
    return [path, plot_kinematics(flight, correct(flight, findings), out / "consistency.png")]


# ---- helpers -----------------------------------------------------------------------------------------------


def _lowpass(x: np.ndarray, cutoff: float, fs: float) -> np.ndarray:
    """Zero-phase order-4 Butterworth low-pass along time (columns of ``x``)."""
    sos = scipy.signal.butter(4, cutoff, fs=fs, output="sos")
    return scipy.signal.sosfiltfilt(sos, x, axis=0)


def _signals(flight: FlightData, cutoff: float) -> dict[str, np.ndarray]:
    """Outputs low-passed at ``cutoff`` Hz by name, the roll angle unwrapped first (an inverted vehicle's
    roll jumps between +-pi; the Euler relations use only its sine and cosine)."""
    y = flight.outputs.copy()
    if "phi" in flight.output_names:
        c = flight.output_names.index("phi")
        y[:, c] = np.unwrap(y[:, c])
    y = _lowpass(y, cutoff, 1.0 / flight.dt)
    return {n: y[:, i] for i, n in enumerate(flight.output_names)}


def _interior(t: np.ndarray, edge: float) -> np.ndarray:
    """Mask of samples more than ``edge`` s from both ends."""
    return (t > t[0] + edge) & (t < t[-1] - edge)


def _ratio(fit: Fit, i: int, sign: float, j: int = 0) -> tuple[float, float]:
    """``sign beta_i / beta_j`` and its delta-method 1-sigma."""
    bi, bj = fit.beta[i], fit.beta[j]
    grad = np.zeros_like(fit.beta)
    grad[i], grad[j] = 1.0 / bj, -bi / bj**2
    return float(sign * bi / bj), float(np.sqrt(grad @ fit.cov @ grad))


def _beyond(deviation: float, sigma: float, kind: str) -> bool:
    """Significant: more than ``N_SIGMA`` sigma and more than the practical tolerance of ``kind``."""
    return bool(np.isfinite(deviation) and np.isfinite(sigma) and abs(deviation) > N_SIGMA * sigma
                and abs(deviation) > TOLERANCE[kind])


def _lag_beyond(tau: float, sigma: float, dt: float) -> bool:
    """Significant lag: beyond :data:`LAG_SIGMA` sigma and at least one sample ``dt`` (s)."""
    return bool(np.isfinite(tau) and np.isfinite(sigma) and abs(tau) > LAG_SIGMA * sigma and abs(tau) >= dt)


def _skip(channels: tuple[str, ...], message: str) -> Finding:
    return Finding("not_checked", tuple(channels), {}, {}, False, message)


def _plain(value: Any) -> Any:
    """JSON-ready floats (``None`` where not finite), kept in a dict where given one."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return float(value) if np.isfinite(value) else None
