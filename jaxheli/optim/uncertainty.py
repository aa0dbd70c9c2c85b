"""Cramer-Rao-style standard errors at an optimum, and which parameters a flight can identify.

Linearised least squares: with ``J`` the Jacobian of the residual vector over the free parameters
(physical units, forward mode: :func:`jaxheli.optim.jacobian.residuals_and_jacobian`) and
``s^2 = RSS / (N_res - rank J - n_nuisance)``, ``cov = s^2 (J^T J)^+``
(``n_nuisance``: unknowns eliminated inside the residuals, e.g. 13 per run whose initial state is estimated by
variable projection, :mod:`jaxheli.sim.shooting`; the Jacobian of the projected residuals marginalises them)
(``rank J = n_free`` when every free parameter is resolved; an unresolved direction costs no degree of
freedom, so a model with unused parameters gives exactly the ordinary least-squares errors). The
pseudo-inverse works on the column-normalised Jacobian (each column divided by its norm, so the cutoff
does not depend on units) and drops singular values below ``rcond`` times the largest. A parameter with
weight above ``null_tol`` in a dropped direction is *unresolved*: the outputs do not determine it (no
effect on them, or an exact trade-off with other parameters); its standard error is ``+inf``.

For the hover model the residuals are :func:`jaxheli.optim.pem.pem`'s: output errors divided by each
measured channel's standard deviation, so ``s^2`` pools the channels as if their normalised noise were
equal.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Literal

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._types import Array, ArrayLike, Bool, Float
from .._xla import quick_jit
from ..bounds import Bounds, Free
from ..data.flight import FlightData
from ..model import N_PARAMS, N_STATES, PARAM_NAMES
from ..problem import Problem, Records, parts
from ..sim.shooting import run_count
from .jacobian import residuals_and_jacobian
from .pem import PEM_DEFAULTS, fitted_problem, residuals


@dataclasses.dataclass(frozen=True)
class Uncertainty:
    """Standard errors of ``theta`` (all arrays in :data:`PARAM_NAMES` order).

    Attributes:
        theta: ``[40]`` the point of linearisation (physical units).
        stderr: ``[40]`` standard errors in the parameters' units: ``+inf`` for unresolved parameters,
            0 for fixed (not free) ones.
        relative: ``[40]`` ``stderr / |theta|`` (``+inf`` where theta is 0 and stderr is not).
        correlation: ``[40, 40]`` correlations of the resolved free parameters; rows and columns of the
            others are those of the identity.
        free: ``[40]`` fitted parameters.
        resolved: ``[40]`` free parameters outside the Jacobian's (numerical) null space.
        singular_values: ``[n_free]`` of the column-normalised Jacobian, descending.
        rank: singular values kept (above ``rcond`` times the largest).
        sigma2: ``s^2``, the residual variance estimate.
        dof: ``N_res - rank``.
        null_space: ``[d, 40]`` the dropped directions of the column-normalised Jacobian (orthonormal rows; zero on
            parameters not free), or ``None`` where the residuals were not finite.
    """

    theta: np.ndarray
    stderr: np.ndarray
    relative: np.ndarray
    correlation: np.ndarray
    free: np.ndarray
    resolved: np.ndarray
    singular_values: np.ndarray
    rank: int
    sigma2: float
    dof: int
    null_space: np.ndarray | None = None

    @property
    def rss(self) -> float:
        """The residuals' sum of squares, ``s^2 (N_res - rank)``."""
        return self.sigma2 * self.dof

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values; per-parameter quantities as ``{name: value}`` (inf as ``"inf"``)."""
        named = lambda v: {n: _json(x) for n, x in zip(PARAM_NAMES, v.tolist())}  # noqa: E731
        return {
            "theta": named(self.theta),
            "stderr": named(self.stderr),
            "relative": named(self.relative),
            "correlation": self.correlation.tolist(),
            "free": [n for n, f in zip(PARAM_NAMES, self.free) if f],
            "resolved": [n for n, r in zip(PARAM_NAMES, self.resolved) if r],
            "singular_values": self.singular_values.tolist(),
            "rank": self.rank,
            "sigma2": self.sigma2,
            "dof": self.dof,
        }


def _json(x: float) -> float | str:
    return x if np.isfinite(x) else "inf"


@quick_jit
def _jacobian(fn: Callable[[Array], Array], theta: Array, idx: Array) -> tuple[Array, Array]:
    """Residuals and their Jacobian over ``theta[idx]`` (forward mode, :mod:`jaxheli.optim.jacobian`)."""
    def of_free(v):
        return fn(theta.at[idx].set(v))

    return residuals_and_jacobian(of_free, theta[idx])


def from_residuals(
    fn: Callable[[Float[Array, "40"]], Float[Array, " m"]],
    theta: Float[ArrayLike, "40"],
    *,
    free: Free = None,
    rcond: float = 1e-8,
    null_tol: float = 1e-6,
    bounds: Bounds | None = None,
    nonfinite: Literal["raise", "unresolved"] = "raise",
    nuisance: int = 0,
) -> Uncertainty:
    """Standard errors of ``theta`` for a residual function ``fn(theta[40]) -> r[m]`` (jit-traceable).

    ``free`` (mask or names, default every axis ``bounds`` leave free; default bounds: the authors') are the
    estimated ones; ``rcond`` is the
    relative singular-value cutoff of the pseudo-inverse, ``null_tol`` the weight in a dropped direction
    that marks a parameter unresolved. Residuals or Jacobian not finite at ``theta`` (a model that diverges)
    raise, or with ``nonfinite="unresolved"`` leave every free parameter unresolved (standard error inf).
    ``nuisance`` unknowns eliminated inside ``fn`` cost degrees of freedom.
    """
    theta = np.asarray(theta, dtype=np.float64)
    if theta.shape != (N_PARAMS,):
        raise ValueError(f"from_residuals: theta must have shape (40,), got {theta.shape}")
    mask = (bounds or Bounds()).free_mask(free)
    idx = np.flatnonzero(mask)
    r, J = (np.asarray(v, dtype=np.float64) for v in _jacobian(fn, jnp.asarray(theta), jnp.asarray(idx)))
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
        if nonfinite == "raise":
            raise ValueError("from_residuals: residuals or Jacobian are not finite at theta")
        stderr = np.where(mask, np.inf, 0.0)
        return Uncertainty(theta, stderr, stderr, np.eye(N_PARAMS), mask, np.zeros(N_PARAMS, bool), np.zeros(0), 0,
                           float("nan"), 0)
    if r.size <= idx.size + nuisance:
        raise ValueError(f"from_residuals: {r.size} residuals for {idx.size} free parameters; need more residuals")
    norms = np.linalg.norm(J, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    _, s, vt = np.linalg.svd(J / norms, full_matrices=False)
    keep = s > rcond * s[0] if s[0] > 0 else np.zeros_like(s, dtype=bool)
    dof = r.size - int(keep.sum()) - nuisance
    sigma2 = float(r @ r / dof)
    null_weight = np.sum(vt[~keep] ** 2, axis=0)
    ok = null_weight <= null_tol
    cov_scaled = (vt[keep].T / s[keep] ** 2) @ vt[keep]
    cov = sigma2 * cov_scaled / np.outer(norms, norms)
    var = np.where(ok, np.maximum(np.diag(cov), 0.0), 0.0)
    scale = np.sqrt(np.outer(var, var))
    corr_free = np.divide(cov, scale, out=np.zeros_like(cov), where=np.outer(ok, ok) & (scale > 0))
    np.fill_diagonal(corr_free, 1.0)

    stderr = np.zeros(N_PARAMS)
    stderr[idx] = np.where(ok, np.sqrt(var), np.inf)
    resolved = np.zeros(N_PARAMS, bool)
    resolved[idx] = ok
    correlation = np.eye(N_PARAMS)
    correlation[np.ix_(idx, idx)] = corr_free
    magnitude = np.abs(theta)
    relative = np.where(stderr == 0, 0.0, stderr / np.where(magnitude > 0, magnitude, 1.0))
    relative = np.where((magnitude == 0) & (stderr > 0), np.inf, relative)
    null_space = np.zeros((int((~keep).sum()), N_PARAMS))
    null_space[:, idx] = vt[~keep]
    return Uncertainty(theta, stderr, relative, correlation, mask, resolved, s, int(keep.sum()), sigma2, dof,
                       null_space)


def standard_errors(
    data: FlightData | Problem | Records,
    theta: Float[ArrayLike, "40"],
    *,
    free: Free = None,
    rcond: float = 1e-8,
    null_tol: float = 1e-6,
    nonfinite: Literal["raise", "unresolved"] = "raise",
    **settings: Any,
) -> Uncertainty:
    """Standard errors of ``theta`` (an optimum of :func:`jaxheli.optim.pem.pem`) on a record.

    The residuals are PEM's normalised output errors on ``data`` (every record's, for
    :class:`~jaxheli.problem.Records`): a :class:`~jaxheli.problem.Problem`, or a
    flight under PEM's defaults with :class:`~jaxheli.problem.Settings` fields in ``settings`` (``outputs``,
    ``segment`` s, ``hold``, ``x0``, ``g``); ``free`` defaults to every axis the problem's bounds leave free;
    ``rcond``, ``null_tol``, ``nonfinite`` as in :func:`from_residuals`.
    """
    problem = fitted_problem(data, PEM_DEFAULTS, **settings)
    mask = problem.bounds.free_mask(free)
    nuisance = sum(N_STATES * run_count(part.n_samples, part.sim.restart_samples) for part in parts(problem)
                   if part.sim.initial == "estimated")
    return from_residuals(eqx.Partial(residuals, problem), theta, free=mask, rcond=rcond, null_tol=null_tol,
                          bounds=problem.bounds, nonfinite=nonfinite, nuisance=nuisance)


def cramer_rao_coverage(
    unc: Uncertainty, truth: Float[ArrayLike, "40"], *, k: float = 3.0, threshold: float = 0.1
) -> dict[str, Any]:
    """How far ``unc.theta`` lies from the known ``truth``, in standard errors (synthetic recovery checks).

    Identifiable: free, resolved and relative standard error at most ``threshold`` (as :func:`identifiable`).
    Returns ``{"k", "threshold", "identifiable": [names], "within": [names within k standard errors],
    "fraction": share of the identifiable within, "z": {name: (theta - truth) / stderr}}`` (``z`` over the
    identifiable parameters).
    """
    truth = np.asarray(truth, dtype=np.float64)
    flags = unc.resolved & (unc.relative <= threshold)
    z = {n: float((unc.theta[i] - truth[i]) / unc.stderr[i]) for i, n in enumerate(PARAM_NAMES) if flags[i]}
    within = [n for n, v in z.items() if abs(v) <= k]
    return {"k": float(k), "threshold": float(threshold), "identifiable": list(z), "within": within,
            "fraction": len(within) / len(z) if z else float("nan"), "z": z}


@dataclasses.dataclass(frozen=True)
class Identifiability:
    """Which parameters a flight identifies at ``theta``, and why.

    Attributes:
        names: the identifiable parameters (free, resolved, relative standard error <= ``threshold``).
        flags: ``[40]`` the same as a mask.
        reasons: ``{name: sentence}`` for every parameter.
        threshold: the relative standard error accepted.
        uncertainty: the standard errors behind the verdict.
    """

    names: tuple[str, ...]
    flags: Bool[np.ndarray, "40"]
    reasons: dict[str, str]
    threshold: float
    uncertainty: Uncertainty

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values."""
        return {
            "identifiable": list(self.names),
            "reasons": dict(self.reasons),
            "threshold": self.threshold,
            "uncertainty": self.uncertainty.to_dict(),
        }


def identifiable(
    data: FlightData | Problem, theta: Float[ArrayLike, "40"], *, threshold: float = 0.1, **options: Any
) -> Identifiability:
    """Parameters whose relative standard error at ``theta`` is at most ``threshold`` (0.1 = 10 %).

    ``options`` are those of :func:`standard_errors`. Each parameter gets a reason: fixed, unresolved
    (with the parameters it trades off against), too uncertain (with its most correlated partner), or
    its relative standard error.
    """
    unc = standard_errors(data, theta, **options)
    flags = unc.resolved & (unc.relative <= threshold)
    return Identifiability(
        names=tuple(n for n, f in zip(PARAM_NAMES, flags) if f),
        flags=flags,
        reasons={n: _reason(i, unc, threshold) for i, n in enumerate(PARAM_NAMES)},
        threshold=float(threshold),
        uncertainty=unc,
    )


def _reason(i: int, unc: Uncertainty, threshold: float) -> str:
    if not unc.free[i]:
        return "fixed: not estimated (pinned by the bounds or held at its given value)"
    if not unc.resolved[i]:
        return "unresolved: the fitted outputs do not determine it (Jacobian null space)"
    rel = unc.relative[i]
    corr = np.abs(unc.correlation[i].copy())
    corr[i] = 0.0
    j = int(np.argmax(corr))
    partner = f"; most correlated with {PARAM_NAMES[j]} (rho = {unc.correlation[i, j]:+.3f})" if corr[j] > 0 else ""
    if rel <= threshold:
        return f"identifiable: relative standard error {rel:.2g}{partner}"
    return f"poorly determined: relative standard error {rel:.2g} > {threshold:g}{partner}"
