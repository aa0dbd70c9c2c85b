"""Sub-sample lag between two signals with its 1-sigma uncertainty, by least squares on a fractional shift.

The model ``target(t) = k (w x(t + tau) + e) + fixed @ beta`` is fitted for the lag ``tau`` (s): first on a
grid of whole-sample shifts (the profile residual sum of squares, its minimum refined by a parabola through
its neighbours), then by Gauss-Newton on the fractional shift, whose last step regresses on the derivative
column ``k w x'(t + tau)`` as well. That column's Newey-West standard error over ``|k|`` is the lag's
1-sigma: the curvature of the least-squares fit at its optimum, widened for autocorrelated residuals.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from jaxtyping import Float

from ._regress import RegressionFit, hac_lstsq, well_posed


@dataclasses.dataclass(frozen=True)
class LagFit:
    """Lag ``tau`` (s, > 0 when ``x`` must be advanced to match: ``x`` lags the target) and its 1-sigma.

    ``fit`` is the final regression on ``[w x(t + tau) + e, w x'(t + tau), *fixed]``; ``converged`` is
    False when Gauss-Newton did not settle or the lag lies within a sample of the search limit.
    """

    tau: float
    sigma: float
    fit: RegressionFit
    converged: bool


def fit_lag(
    t: Float[np.ndarray, "N"],
    target: Float[np.ndarray, "N"],
    x: Float[np.ndarray, "N"],
    fixed: list[Float[np.ndarray, "N"]],
    *,
    max_lag: float,
    edge: float,
    bandwidth: int,
    weight: Float[np.ndarray, "N"] | float = 1.0,
    offset: Float[np.ndarray, "N"] | float = 0.0,
) -> LagFit | None:
    """Fit the lag of ``x`` against ``target`` within ``+-max_lag`` s (samples within ``edge + max_lag`` s
    of either end are left out); ``bandwidth`` is the least Newey-West bandwidth, samples. ``None`` when the
    regressors are collinear or constant."""
    dt = float(np.mean(np.diff(t)))
    keep = (t > t[0] + edge + max_lag) & (t < t[-1] - edge - max_lag)
    y = target[keep]

    def columns(tau: float, slope: bool) -> np.ndarray:
        shifted = np.interp(t + tau, t, x)
        cols = [weight * shifted + offset] + ([weight * np.gradient(shifted, dt)] if slope else [])
        return np.stack([np.broadcast_to(c, t.shape) for c in cols + fixed], axis=1)[keep]

    if not well_posed(columns(0.0, True)):
        return None
    n = int(max_lag / dt)
    rss = np.array([_rss(y, columns(k * dt, False)) for k in range(-n, n + 1)])
    i = int(np.argmin(rss))
    tau = (i - n) * dt
    if 0 < i < 2 * n and rss[i - 1] - 2 * rss[i] + rss[i + 1] > 0:
        tau += 0.5 * dt * (rss[i - 1] - rss[i + 1]) / (rss[i - 1] - 2 * rss[i] + rss[i + 1])
    converged = False
    for _ in range(12):
        beta, *_ = np.linalg.lstsq(columns(tau, True), y, rcond=None)
        step = beta[1] / beta[0]
        tau = float(np.clip(tau + step, -max_lag, max_lag))
        if abs(step) < 1e-3 * dt:
            converged = True
            break
    fit = hac_lstsq(y, columns(tau, True), min_bandwidth=bandwidth)
    return LagFit(tau, float(fit.se[1] / abs(fit.beta[0])), fit, converged and abs(tau) < max_lag - dt)


def _rss(y: Float[np.ndarray, "N"], X: Float[np.ndarray, "N m"]) -> float:
    """Residual sum of squares of the least-squares fit of ``y`` on ``X``."""
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    return float(np.sum((y - X @ beta) ** 2))
