"""Stage 1, kinematics: Euler angles against body rates, per axis roll and pitch.

The full Euler relations ``phi' = p + (q sin phi + r cos phi) tan theta`` and ``theta' = q cos phi - r sin phi``
are fitted as ``angle' = s (c rate(t + tau) + e - c b - c d (t - t_mid))`` on low-passed signals, with ``c`` the
rate's coefficient and ``e`` the cross-axis terms. Estimates: the time-scale factor ``k = 1 / s`` (recorded time /
true time; all axes agree when the time base is off, one axis alone means a gyro scale error), the lag ``tau``
(s, > 0 when the rate channel lags the angle; :func:`~.._lag.fit_lag`: a whole-sample grid, a parabola, then
Gauss-Newton on a fractional shift), the rate bias ``b`` (rad/s) and its drift ``d`` (rad/s^2).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.stats
from jaxtyping import Float

from ...data.flight import FlightData
from .._finding import Finding, beyond, lag_beyond, skip
from .._lag import fit_lag
from .signals import EDGE_S, MAX_LAG_S, MIN_DURATION_S, ratio, signals

KINEMATIC_CUTOFF_HZ = 5.0
"""Low-pass (zero-phase Butterworth, order 4) applied before the kinematic regression; above it gyros
carry rotor vibration (data README fact 2)."""

_AXES = (("roll", "phi", "p"), ("pitch", "theta", "q"))


@dataclasses.dataclass(frozen=True)
class _AxisFit:
    """Kinematic fit of one axis: scale ``s``, lag ``tau`` (s), rate bias ``b`` and drift ``d`` with sigmas."""

    axis: str
    angle: str
    rate: str
    values: dict[str, float]
    sigmas: dict[str, float]
    converged: bool


def time_scale(flight: FlightData) -> tuple[list[Finding], list[_AxisFit]]:
    """The common time-scale factor of all checkable axes (first finding) and the per-axis fits."""
    fits, skipped = kinematic_fits(flight)
    if not fits:
        return [skip(("time",), "Time base not checked: no axis has both an Euler angle and a varying body "
                                 "rate."), *skipped], fits
    k = np.array([1.0 / f.values["s"] for f in fits])
    sk = np.array([f.sigmas["s"] / f.values["s"] ** 2 for f in fits])
    w = 1.0 / sk**2
    common, sigma = float(np.sum(w * k) / np.sum(w)), float(1.0 / np.sqrt(np.sum(w)))
    chi2 = float(np.sum(w * (k - common) ** 2))
    agree = len(fits) == 1 or scipy.stats.chi2.sf(chi2, len(fits) - 1) > 1e-3
    per_axis = ", ".join(f"{f.axis} {ki:.4f} +- {si:.4f}" for f, ki, si in zip(fits, k, sk))
    significant = agree and beyond(common - 1.0, sigma, "time_scale")
    note = ("the axes agree" if agree else "the axes disagree, so it is a gyro scale error, not the time base")
    message = (f"Time-scale factor (recorded / true time) {common:.4f} +- {sigma:.4f} (1 sigma; {per_axis}); "
               f"{note}.")
    return [Finding("time_scale", ("time",), common, sigma, significant, message), *skipped], fits


def kinematic_fits(flight: FlightData) -> tuple[list[_AxisFit], list[Finding]]:
    """Fit every roll / pitch axis whose angle and rate are present and not constant; ``not_checked``
    findings (with the reason) for the others."""
    cutoff, terms = kinematic_terms(flight)
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
        skipped.append(skip((rate, angle), f"{rate} against d{angle}/dt (lag, scale, bias) not checked: {why}."))
    return fits, skipped


def kinematic_terms(flight: FlightData) -> tuple[float, dict[tuple[str, str, str], tuple[np.ndarray, ...]]]:
    """Low-pass cutoff (Hz) and, per checkable axis, the filtered angle, rate, rate coefficient ``c`` and
    cross-axis term ``e`` of the Euler relation ``angle' = c rate + e`` (missing rates count as zero)."""
    names = flight.output_names
    fs = 1.0 / flight.dt
    cutoff = min(KINEMATIC_CUTOFF_HZ, 0.4 * fs)
    if flight.duration - 2 * EDGE_S < MIN_DURATION_S:
        return cutoff, {}
    sig = signals(flight, cutoff)
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
    """Lag by :func:`~.._lag.fit_lag`, least squares for the rest:
    ``angle' = s (c rate(t + tau) + e - c b - c d t')``."""
    tc = t - 0.5 * (t[0] + t[-1])
    lag = fit_lag(t, np.gradient(angle, dt), simpson(rate), [c, c * tc], max_lag=MAX_LAG_S, edge=EDGE_S,
                  bandwidth=int(1.0 / (cutoff * dt)), weight=c, offset=simpson(e))
    if lag is None:
        return None
    fit = lag.fit
    b, sig_b = ratio(fit, 2, -1.0)
    d, sig_d = ratio(fit, 3, -1.0)
    values = {"s": float(fit.beta[0]), "tau": lag.tau, "b": b, "d": d}
    sigmas = {"s": float(fit.se[0]), "tau": lag.sigma, "b": sig_b, "d": sig_d}
    return values, sigmas, lag.converged


def simpson(x: Float[np.ndarray, "N"]) -> Float[np.ndarray, "N"]:
    """``x`` averaged as Simpson's rule averages it over two steps, ``(x[k-1] + 4 x[k] + x[k+1]) / 6`` (the ends
    kept): the central difference of the angle (``np.gradient``) is the two-step mean of its rate, so the rate is
    compared in the same form. Unmatched, the difference's gain ``sin(w dt) / (w dt)`` (w in rad/s, dt in s) reads
    as a time-scale error at low sample rates (7 % at 2 Hz sampled at 20 Hz); matched, the two gains agree to
    ``(w dt)^4 / 180``."""
    out = np.array(x, dtype=float)
    out[1:-1] = (x[:-2] + 4.0 * x[1:-1] + x[2:]) / 6.0
    return out


def axis_findings(fits: list[_AxisFit], flight: FlightData) -> list[Finding]:
    """Gyro scale, lag, bias and drift findings of each fitted axis (on the time-corrected record)."""
    out = []
    span = flight.duration
    for f in fits:
        v, sg = f.values, f.sigmas
        g_scale = 1.0 / v["s"]
        sig_g = sg["s"] / v["s"] ** 2
        out.append(Finding("rate_scale", (f.rate,), g_scale, sig_g, beyond(g_scale - 1, sig_g, "rate_scale"),
                           f"{f.rate} reads {g_scale:.4f} +- {sig_g:.4f} (1 sigma) times the rate implied by "
                           f"d{f.angle}/dt."))
        lag_ok = f.converged and lag_beyond(v["tau"], sg["tau"], flight.dt)
        out.append(Finding("kinematic_lag", (f.rate, f.angle), v["tau"], sg["tau"], lag_ok,
                           f"{f.rate} lags {f.angle} by {1e3 * v['tau']:.1f} +- {1e3 * sg['tau']:.1f} ms (1 sigma)"
                           + ("." if f.converged else "; the lag search did not converge or reached its limit.")))
        out.append(Finding("rate_bias", (f.rate,), v["b"], sg["b"], beyond(v["b"], sg["b"], "rate_bias"),
                           f"{f.rate} has a bias of {v['b']:.4f} +- {sg['b']:.4f} rad/s (1 sigma) against "
                           f"d{f.angle}/dt."))
        out.append(Finding("rate_drift", (f.rate,), v["d"], sg["d"],
                           beyond(v["d"] * span, sg["d"] * span, "rate_drift"),
                           f"{f.rate} bias drifts by {v['d']:.2e} +- {sg['d']:.2e} rad/s^2 (1 sigma), "
                           f"{v['d'] * span:.4f} rad/s over the {span:.3g} s record."))
    return out
