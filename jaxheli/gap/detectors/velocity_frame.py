"""Stages 2 and 3, velocities against attitude: the velocity frame, and the attitude bias and drift.

Near hover ``u' = -g theta + ...`` and ``v' = g phi + ...``. Each velocity derivative is regressed on the attitude
angles, the velocities (speed derivatives), the body rates and the centred sticks (rotor flapping,
quasi-steady), a constant and time; the attitude columns give the 2 x 2 map ``T`` from true to recorded
velocities, split into a rotation ``alpha`` (rad) and a signed scale per channel (-1: sign flipped). The same
regression's constant and time terms give the roll / pitch offset (rad) at which the helicopter would not
accelerate, and its drift (rad/s). A velocity drift looks the same (``g`` times the offset, m/s^2); the two
cannot be told apart from these channels.
"""

from __future__ import annotations

import math

import numpy as np
from jaxtyping import Float

from ...data.flight import FlightData
from ...model import G_SI, INPUT_NAMES
from .._finding import N_SIGMA, Finding, beyond, skip
from .._regress import RegressionFit, hac_lstsq, well_posed
from .signals import EDGE_S, VELOCITY_CUTOFF_HZ, interior, lowpass, ratio, signals

_VELOCITIES = (("u", "theta", -1.0), ("v", "phi", 1.0))
"""Velocity, its attitude partner and the sign of ``g`` in ``velocity' = sign g angle``."""


def _velocity_fits(flight: FlightData) -> tuple[list[tuple[str, str, float]], list[RegressionFit], list[Finding]]:
    """Regress each velocity derivative on attitude, velocities, rates, centred sticks, 1 and time."""
    names = flight.output_names
    pairs, skipped = [], []
    for vel, angle, sign in _VELOCITIES:
        if not {vel, angle} <= set(names):
            skipped.append(skip((vel, angle), f"{vel} against {angle} not checked: the flight lacks "
                                               f"{vel if vel not in names else angle}."))
        elif np.ptp(flight.output(vel)) == 0 or np.ptp(flight.output(angle)) == 0:
            skipped.append(skip((vel, angle), f"{vel} against {angle} not checked: a channel is constant "
                                               "(no data)."))
        else:
            pairs.append((vel, angle, sign))
    if not pairs:
        return pairs, [], skipped
    fs = 1.0 / flight.dt
    cutoff = min(VELOCITY_CUTOFF_HZ, 0.4 * fs)
    sticks = lowpass(flight.inputs - flight.inputs.mean(axis=0), cutoff, fs)
    sig = signals(flight, cutoff)
    tc = flight.time - 0.5 * (flight.time[0] + flight.time[-1])
    nuisance = [sig[n] for n in ("p", "q") if n in sig and np.ptp(sig[n]) > 0]
    nuisance += [sticks[:, j] for j in range(len(INPUT_NAMES)) if np.ptp(flight.inputs[:, j]) > 0]
    nuisance += [np.gradient(x, flight.dt) for x in nuisance]
    X = np.stack([sig[a] for _, a, _ in pairs] + [sig[v] for v, _, _ in pairs] + nuisance
                 + [np.ones_like(tc), tc], axis=1)
    keep = interior(flight.time, EDGE_S)
    if not well_posed(X[keep]):
        return [], [], skipped + [skip(tuple(v for v, _, _ in pairs),
                                        "velocity checks not possible: the regressors are collinear.")]
    fits = [hac_lstsq(np.gradient(sig[v], flight.dt)[keep], X[keep], min_bandwidth=int(1.0 / (cutoff * flight.dt)))
            for v, _, _ in pairs]
    return pairs, fits, skipped


def velocity_frame(flight: FlightData) -> list[Finding]:
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
        return out + [Finding("velocity_scale", (vel,), s, sigma, beyond(s - 1.0, sigma, "velocity_scale"),
                              f"{vel} {_flip(s, sigma)}a scale of {s:.3f} +- {sigma:.3f} (1 sigma) against g {angle}.")]
    alpha, sig_alpha, scales, sig_scales = _split_frame(gain, sd)
    vels = tuple(v for v, _, _ in pairs)
    est = {"rotation": alpha, **{f"scale_{v}": s for v, s in zip(vels, scales)}}
    unc = {"rotation": sig_alpha, **{f"scale_{v}": s for v, s in zip(vels, sig_scales)}}
    parts = frame_parts(est, unc)
    scale_text = ", ".join(f"{v} {_flip(s, ss)}scale {s:.3f} +- {ss:.3f}" for v, s, ss in zip(vels, scales, sig_scales))
    return out + [Finding("velocity_frame", vels, est, unc, any(parts.values()),
                          f"The velocity axes are rotated by {math.degrees(alpha):.2f} +- {math.degrees(sig_alpha):.2f} "
                          f"deg about z from the attitude-implied body axes; {scale_text} (1 sigma).")]


def frame_parts(est: dict[str, float], unc: dict[str, float]) -> dict[str, bool]:
    """Which parts of a ``velocity_frame`` estimate are significant."""
    return {k: beyond(est[k] - (k != "rotation"), unc[k], "velocity_rotation" if k == "rotation" else "velocity_scale")
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


def attitude_bias(flight: FlightData) -> list[Finding]:
    """Attitude offsets and drifts from the constant and time terms of the velocity regression."""
    pairs, fits, _ = _velocity_fits(flight)
    out = []
    span = flight.duration
    for j, ((vel, angle, _), fit) in enumerate(zip(pairs, fits)):
        bias, sig_b = ratio(fit, -2, -1.0, j)
        drift, sig_d = ratio(fit, -1, -1.0, j)
        g = abs(fit.beta[j])
        out.append(Finding("attitude_bias", (angle,), bias, sig_b, beyond(bias, sig_b, "attitude_bias"),
                           f"{angle} is offset by {bias:.4f} +- {sig_b:.4f} rad (1 sigma) from the attitude at which "
                           f"{vel} would not accelerate (or {vel} drifts by {g * bias:.3f} m/s^2)."))
        out.append(Finding("attitude_drift", (angle,), drift, sig_d,
                           beyond(drift * span, sig_d * span, "attitude_drift"),
                           f"{angle} drifts by {drift:.2e} +- {sig_d:.2e} rad/s (1 sigma), {drift * span:.4f} rad "
                           f"over the {span:.3g} s record."))
    return out


def frame_matrix(est: dict[str, float], unc: dict[str, float], vels: tuple[str, ...]) -> Float[np.ndarray, "2 2"]:
    """``R(rotation) diag(scale_u, scale_v)`` of the significant parts of a ``velocity_frame`` estimate."""
    parts = frame_parts(est, unc)
    a = est["rotation"] if parts["rotation"] else 0.0
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return rot @ np.diag([applied_scale(est[f"scale_{v}"], unc[f"scale_{v}"]) if parts[f"scale_{v}"] else 1.0
                          for v in vels])


def applied_scale(s: float, sigma: float) -> float:
    """The velocity scale ``correct`` divides by: the sign always, the magnitude only where it differs from 1
    significantly."""
    return math.copysign(abs(s) if beyond(abs(s) - 1.0, sigma, "velocity_scale") else 1.0, s)
