"""Model-structure determination: fix the parameters a flight cannot determine, and fit again (SIDPAC, CIFER).

At a fitted ``theta`` the Cramer-Rao standard errors (:func:`~jaxheli.optim.uncertainty.standard_errors`) say which
free parameters the record determines. Each round fixes

- the *unresolved* ones (in the Jacobian's null space: an input that never moves, an exact trade-off), one per
  dropped direction: a pivoted QR of the null-space basis picks the parameter carrying most of each direction, so of
  an exactly collinear pair one is fixed and the other keeps the pair's effect;
- the resolved ones whose relative Cramer-Rao bound ``stderr / |theta|`` exceeds ``max_relative_se``, or that are
  correlated above ``max_correlation`` with another free parameter, taken in order of decreasing relative bound:
  a parameter fixed in a round protects its correlated partners (``|rho| > max_correlation``) from being fixed in
  the same round, so of a correlated pair the one with the larger relative bound goes and the other is judged
  again, at the next round's re-fit, without it (one parameter of a pair at a time, as stepwise regression removes
  terms).

Each fixed parameter is held at the prior model's value when a prior is given, else at 0 when the box holds 0 (a
term the flight cannot see is dropped), else at the nearest bound; the re-fit pins it there (``lower = upper``,
the box's own mechanism) and runs the same local fit as the identification (PEM, or the polish's output-error least
squares), from the fitted point. Rounds go on until nothing more is fixed or :data:`MAX_ROUNDS` re-fits.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal

import numpy as np
import scipy.linalg

from .._types import ArrayLike, Float
from ..bounds import Bounds
from ..data.flight import FlightData
from ..model import PARAM_NAMES
from ..problem import Problem, Records
from .output_error import output_error, output_error_problem
from .pem import PEM_DEFAULTS, fitted_problem, pem
from .prior import Prior
from .uncertainty import Uncertainty, standard_errors

LocalFit = Literal["pem", "output-error"]

MAX_RELATIVE_SE = 0.2
"""Relative Cramer-Rao bound (``stderr / |theta|``) above which a parameter is fixed: CIFER's guideline (Tischler &
Remple, *Aircraft and Rotorcraft System Identification*, Cramer-Rao bound <= 20 % of the value for an acceptable
estimate). Time-domain bounds from coloured residuals are optimistic (SIDPAC corrects them by a factor of several),
so 20 % on ours fixes only parameters that are poorly determined even by an optimistic measure."""
MAX_CORRELATION = 0.95
"""Absolute correlation of two free parameters' estimates above which one of them is fixed."""
MAX_ROUNDS = 3
"""Most fix-and-re-fit rounds."""


@dataclasses.dataclass(frozen=True)
class FixedParameter:
    """A parameter the determination fixed.

    Attributes:
        name, value: the parameter and the value it is held at (its units).
        reason: a sentence: unresolved, its relative Cramer-Rao bound, or the correlated partner and ``rho``.
        round: the round (1, 2, ...) that fixed it.
        relative_se: its relative Cramer-Rao bound when fixed (``inf`` when unresolved).
        partner, rho: the free parameter it was most correlated with, and the correlation (``None`` if none).
        source: where ``value`` comes from: ``"prior"``, ``"zero"`` or ``"bound"``.
    """

    name: str
    value: float
    reason: str
    round: int
    relative_se: float
    partner: str | None
    rho: float | None
    source: Literal["prior", "zero", "bound"]

    def to_json(self) -> dict[str, Any]:
        """JSON-ready values (``relative_se`` ``"inf"`` when unresolved)."""
        out = dataclasses.asdict(self)
        out["relative_se"] = self.relative_se if np.isfinite(self.relative_se) else "inf"
        return out


@dataclasses.dataclass(frozen=True)
class StructureResult:
    """Outcome of :func:`determine_structure`.

    Attributes:
        fixed: the fixed parameters, in the order fixed.
        theta_start, theta: ``[40]`` the fitted point it started from and the re-fitted parameters.
        rss_start, rss: the local fit's output-error sum of squares (normalised residuals; no prior term) at
            ``theta_start`` with every parameter free and at ``theta`` with the fixed ones held.
        lower, upper: ``[40]`` the box of the last re-fit (each fixed parameter pinned at its value).
        rounds: per round, the names fixed and the re-fit's sum of squares before and after.
        uncertainty: the standard errors at ``theta`` (fixed parameters not free).
        settings: ``local_fit``, ``max_relative_se``, ``max_correlation``, ``max_rounds``, ``prior`` (given or not).
    """

    fixed: tuple[FixedParameter, ...]
    theta_start: np.ndarray
    theta: np.ndarray
    rss_start: float
    rss: float
    lower: np.ndarray
    upper: np.ndarray
    rounds: tuple[dict[str, Any], ...]
    uncertainty: Uncertainty
    settings: dict[str, Any]

    def fixed_dict(self) -> dict[str, dict[str, Any]]:
        """``{name: {value, reason, ...}}`` of the fixed parameters (JSON-ready)."""
        return {f.name: {k: v for k, v in f.to_json().items() if k != "name"} for f in self.fixed}

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary (without the standard errors)."""
        return {"fixed": self.fixed_dict(), "rss_start": self.rss_start, "rss": self.rss,
                "rounds": list(self.rounds), "settings": dict(self.settings)}


@dataclasses.dataclass(frozen=True)
class _Choice:
    index: int
    reason: str
    relative_se: float
    partner: str | None
    rho: float | None


def select_fixed(
    unc: Uncertainty, *, max_relative_se: float = MAX_RELATIVE_SE, max_correlation: float = MAX_CORRELATION
) -> list[_Choice]:
    """The parameters one round fixes (see the module): unresolved ones, one per null direction, then resolved ones
    above ``max_relative_se`` or in a pair correlated above ``max_correlation`` (the larger relative bound of the
    pair), each protecting its correlated partners in this round. Nothing when the standard errors were not
    finite (``unc.rank == 0``: a diverging model says nothing of structure)."""
    if unc.rank == 0:
        return []
    chosen: list[_Choice] = []
    unresolved = np.flatnonzero(unc.free & ~unc.resolved)
    if unresolved.size and unc.null_space is not None and unc.null_space.shape[0]:
        basis = unc.null_space[:, unresolved]
        _, _, pivots = scipy.linalg.qr(basis, mode="economic", pivoting=True)
        for k in pivots[: min(basis.shape)]:
            chosen.append(_Choice(int(unresolved[k]), "unresolved: the fitted outputs do not determine it "
                                  "(Jacobian null space)", float("inf"), None, None))
    corr = np.abs(unc.correlation) * np.outer(unc.resolved, unc.resolved)
    np.fill_diagonal(corr, 0.0)
    resolved = np.flatnonzero(unc.resolved)
    protected: set[int] = set()
    for i in sorted(resolved, key=lambda j: -unc.relative[j]):
        if i in protected:
            continue
        rel, j = float(unc.relative[i]), int(np.argmax(corr[i]))
        partner = (PARAM_NAMES[j], float(unc.correlation[i, j])) if corr[i, j] > 0 else (None, None)
        if rel > max_relative_se:
            reason = f"relative Cramer-Rao bound {rel:.3g} > {max_relative_se:g}"
        elif corr[i, j] > max_correlation:
            reason = (f"correlated with {PARAM_NAMES[j]} (rho = {unc.correlation[i, j]:+.3f}, |rho| > "
                      f"{max_correlation:g}); its relative Cramer-Rao bound {rel:.3g} is the larger "
                      f"({PARAM_NAMES[j]}: {unc.relative[j]:.3g})")
        else:
            continue
        chosen.append(_Choice(int(i), reason, rel, *partner))
        protected.update(int(k) for k in np.flatnonzero(corr[i] > max_correlation))
    return chosen


def fixed_value(
    index: int, bounds: Bounds, prior: Prior | None = None
) -> tuple[float, Literal["prior", "zero", "bound"]]:
    """The value parameter ``index`` is fixed at: the prior's (clipped into the box) when given, else 0 when the
    box holds it, else the nearest bound; and which of the three it is."""
    lo, hi = float(bounds.lower[index]), float(bounds.upper[index])
    if prior is not None:
        return float(np.clip(float(prior.mean[index]), lo, hi)), "prior"
    if lo <= 0.0 <= hi:
        return 0.0, "zero"
    return (lo if abs(lo) < abs(hi) else hi), "bound"


def determine_structure(
    data: FlightData | Problem | Records,
    theta: Float[ArrayLike, "40"],
    *,
    local_fit: LocalFit = "pem",
    max_relative_se: float = MAX_RELATIVE_SE,
    max_correlation: float = MAX_CORRELATION,
    prior: Prior | None = None,
    max_rounds: int = MAX_ROUNDS,
    max_steps: int = 100,
    rounds: int = 4,
    **settings: Any,
) -> StructureResult:
    """Fix the parameters ``data`` cannot determine at the fitted ``theta[40]`` and re-fit, until nothing more is
    fixed or after ``max_rounds`` re-fits (see the module).

    Args:
        data: the record as the identification fitted it: a :class:`~jaxheli.problem.Problem` /
            :class:`~jaxheli.problem.Records` (its box applies), or a flight under PEM's defaults and ``settings``.
        theta: the fitted parameters (an optimum of ``local_fit``).
        local_fit: ``"pem"`` (:func:`~jaxheli.optim.pem.pem` on ``data`` as it is; standard errors on the same
            predictor) or ``"output-error"`` (the polish's fit, :func:`~jaxheli.optim.output_error.output_error`,
            ``rounds`` rounds; standard errors with its restarts at the current point).
        max_relative_se, max_correlation: the thresholds (:data:`MAX_RELATIVE_SE`, :data:`MAX_CORRELATION`).
        prior: the values fixed parameters take (and a prior term in every re-fit,
            :class:`~jaxheli.optim.prior.Prior`); ``None``: 0, or the nearest bound where the box excludes 0.
        max_steps: solver steps of each re-fit (per round for output error).
    """
    if local_fit not in ("pem", "output-error"):
        raise ValueError(f"determine_structure: local_fit must be 'pem' or 'output-error', got {local_fit!r}")
    if max_rounds < 1 or not 0 < max_correlation < 1 or not max_relative_se > 0:
        raise ValueError("determine_structure: need max_rounds >= 1, 0 < max_correlation < 1, max_relative_se > 0")
    problem = fitted_problem(data, PEM_DEFAULTS, **settings)
    start = np.asarray(theta, dtype=np.float64)
    lower, upper = (np.asarray(v, np.float64).copy() for v in (problem.bounds.lower, problem.bounds.upper))
    current, fixed, history = start, [], []
    unc = _errors(problem, current, local_fit)
    rss_start = unc.rss
    for k in range(1, max_rounds + 1):
        choices = select_fixed(unc, max_relative_se=max_relative_se, max_correlation=max_correlation)
        if not choices:
            break
        box = Bounds(lower, upper)
        for c in choices:
            value, source = fixed_value(c.index, box, prior)
            lower[c.index] = upper[c.index] = value
            fixed.append(FixedParameter(PARAM_NAMES[c.index], value, c.reason, k, c.relative_se, c.partner, c.rho,
                                        source))
        pinned = problem.variant(lower=tuple(lower), upper=tuple(upper))
        held = np.clip(current, lower, upper)
        if local_fit == "pem":
            res = pem(pinned, start=held, max_steps=max_steps, prior=prior)
        else:
            res = output_error(pinned, held, rounds=rounds, max_steps=max_steps, prior=prior)
        current = res.theta
        history.append({"round": k, "fixed": [PARAM_NAMES[c.index] for c in choices],
                        "rss_start": res.rss_start, "rss": res.rss, "n_steps": res.n_steps, "result": res.result})
        unc = _errors(pinned, current, local_fit)
    return StructureResult(
        fixed=tuple(fixed), theta_start=start, theta=current, rss_start=rss_start, rss=unc.rss,
        lower=lower, upper=upper, rounds=tuple(history), uncertainty=unc,
        settings={"local_fit": local_fit, "max_relative_se": max_relative_se, "max_correlation": max_correlation,
                  "max_rounds": max_rounds, "prior": prior is not None})


def _errors(problem: Problem | Records, theta: np.ndarray, local_fit: LocalFit) -> Uncertainty:
    """Standard errors at ``theta`` on the local fit's residuals (output error: its restarts at ``theta``)."""
    scored = output_error_problem(problem, theta) if local_fit == "output-error" else problem
    return standard_errors(scored, theta, nonfinite="unresolved")
