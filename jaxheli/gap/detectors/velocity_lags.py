"""Stage 4, velocity lags: each body velocity against its attitude-driven acceleration.

``u, v, w`` against the kinematic acceleration, gravity and the rate cross terms of ``V' = F/m - omega x V + g``
(``u' = r v - q w - g sin theta + X``, ...), with a scale, a drag term, the collective for ``w``, a constant and
time standing in for the unmeasured force. The lag includes the rotor's own lag behind the fuselage (its
flapping time constant) where the force model misses it, and ``w``'s is weak unless the attitude varies: its
uncertainty says so. A lag is significant only where the pair is identified (the acceleration's gain beyond
3 sigma of zero), and not corrected: a lagging sensor and the rotor's own lag look the same here.
"""

from __future__ import annotations

import numpy as np

from ...data.flight import FlightData
from ...model import G_SI, INPUT_NAMES
from .._finding import N_SIGMA, Finding, lag_beyond, skip
from .._lag import fit_lag
from .signals import EDGE_S, MAX_LAG_S, VELOCITY_CUTOFF_HZ, lowpass, signals

_SPEEDS = (("u", ("theta",)), ("v", ("phi",)), ("w", ("phi", "theta")))
"""Body velocity and the Euler angles its gravity component needs."""


def velocity_lags(flight: FlightData) -> list[Finding]:
    """Lag of each body velocity against its kinematic acceleration (:func:`_speed_terms`), by
    :func:`~.._lag.fit_lag` with a scale, a drag term (the velocity itself), the collective for ``w``, a
    constant and time as nuisance; > 0 when the velocity channel lags."""
    names = flight.output_names
    fs = 1.0 / flight.dt
    cutoff = min(VELOCITY_CUTOFF_HZ, 0.4 * fs)
    sig = signals(flight, cutoff)
    col = lowpass(flight.inputs[:, INPUT_NAMES.index("col")] - flight.inputs[:, INPUT_NAMES.index("col")].mean(),
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
            out.append(skip(channels, f"{vel} lag not checked: {why}."))
            continue
        fixed = [np.ones_like(tc), tc, sig[vel]] + ([col] if vel == "w" and np.ptp(col) > 0 else [])
        lag = fit_lag(flight.time, np.gradient(sig[vel], flight.dt), _speed_terms(sig, g)[vel], fixed,
                      max_lag=MAX_LAG_S, edge=EDGE_S, bandwidth=int(1.0 / (cutoff * flight.dt)))
        if lag is None:
            out.append(skip(channels, f"{vel} lag not checked: the regressors are collinear."))
            continue
        tau, sigma = -lag.tau, lag.sigma
        gain, sig_gain = float(lag.fit.beta[0]), float(lag.fit.se[0])
        identified = abs(gain) > N_SIGMA * sig_gain
        note = (f"; the pair is not identified (gain within {N_SIGMA:g} sigma of 0)" if not identified else
                "; the lag search did not converge or reached its limit" if not lag.converged else "")
        out.append(Finding("velocity_lag", channels, tau, sigma,
                           identified and lag.converged and lag_beyond(tau, sigma, flight.dt),
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
