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
squares), from the fitted point: output error in one round, without the ladder of short runs a population
optimiser's rough start needs (the same compiled solver as the polish's). A round's fixes stand only when the
re-fit's sum of squares rises by no more than an extra-sum-of-squares test allows (:data:`LEVEL`), every sum over
the runs of the free fit (output error shortens the runs of an unstable model, so a re-fit judged on its own runs
could lower its sum by turning unstable); otherwise the round tries fewer (the unresolved ones with the
resolved one of largest relative bound, then the unresolved ones alone), and ends the determination when none
passes. Rounds go on until nothing more is fixed or after :data:`MAX_ROUNDS`.

The test is needed: a 20 % relative bound does not say the flight is indifferent to a parameter (fixing every
parameter so bounded can nearly double the training flight's sum of squares); the test does.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal

import numpy as np
import scipy.linalg
import scipy.stats

from .._types import ArrayLike, Float
from ..bounds import Bounds
from ..data.flight import FlightData
from ..model import PARAM_NAMES
from ..problem import Problem, Records
from .output_error import output_error, output_error_problem
from .pem import PEM_DEFAULTS, PEMResult, fitted_problem, pem
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
MAX_ROUNDS = 4
"""Most rounds (each tries up to three sets to fix, :func:`determine_structure`)."""
LEVEL = 0.05
"""Significance level of the extra-sum-of-squares test a round's fixes must pass: the re-fit's rise of the sum of
squares, in units of the free fit's residual variance ``s^2``, at most the ``1 - LEVEL`` quantile of chi-square with
as many degrees of freedom as parameters fixed (SIDPAC's stepwise regression removes a term only when its partial F
is small). Residuals of a real flight are coloured, so ``s^2`` is small and the test errs towards keeping
parameters free."""


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
    unresolved: bool
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
            chosen.append(_Choice(True, int(unresolved[k]), "unresolved: the fitted outputs do not determine it "
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
        if rel > max_relative_se and unc.theta[i] == 0.0:
            reason = f"Cramer-Rao bound {unc.stderr[i]:.3g} at the value 0 (relative bound inf > {max_relative_se:g})"
        elif rel > max_relative_se:
            reason = f"relative Cramer-Rao bound {rel:.3g} > {max_relative_se:g}"
        elif corr[i, j] > max_correlation:
            reason = (f"correlated with {PARAM_NAMES[j]} (rho = {unc.correlation[i, j]:+.3f}, |rho| > "
                      f"{max_correlation:g}); its relative Cramer-Rao bound {rel:.3g} is the larger "
                      f"({PARAM_NAMES[j]}: {unc.relative[j]:.3g})")
        else:
            continue
        chosen.append(_Choice(False, int(i), reason, rel, *partner))
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
    level: float = LEVEL,
    max_steps: int = 100,
    rounds: int = 1,
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
            ``rounds`` rounds, default 1: a re-fit from an optimum).
        max_relative_se, max_correlation: the thresholds (:data:`MAX_RELATIVE_SE`, :data:`MAX_CORRELATION`).
        prior: the values fixed parameters take (and a prior term in every re-fit,
            :class:`~jaxheli.optim.prior.Prior`); ``None``: 0, or the nearest bound where the box excludes 0.
        max_rounds, level: the most rounds, and the significance level of each round's test (:data:`LEVEL`).
        max_steps, rounds: solver steps of each re-fit (per round for output error), and output error's rounds.

    A round fixes what :func:`select_fixed` chooses only if the re-fit passes the extra-sum-of-squares test
    (:data:`LEVEL`); otherwise it tries the unresolved ones with the worst resolved one, then the unresolved ones
    alone; when none passes, the determination ends. ``rounds`` of the result lists every try, accepted or not.
    """
    if local_fit not in ("pem", "output-error"):
        raise ValueError(f"determine_structure: local_fit must be 'pem' or 'output-error', got {local_fit!r}")
    if max_rounds < 1 or not 0 < max_correlation < 1 or not max_relative_se > 0:
        raise ValueError("determine_structure: need max_rounds >= 1, 0 < max_correlation < 1, max_relative_se > 0")
    problem = fitted_problem(data, PEM_DEFAULTS, **settings)
    start = np.asarray(theta, dtype=np.float64)
    lower, upper = (np.asarray(v, np.float64).copy() for v in (problem.bounds.lower, problem.bounds.upper))
    current, fixed, history = start, [], []
    unc = _errors(problem, current, local_fit, start)
    rss_start = unc.rss
    for k in range(1, max_rounds + 1):
        choices = select_fixed(unc, max_relative_se=max_relative_se, max_correlation=max_correlation)
        accepted = None
        n_free = int(np.sum(upper > lower))
        for tried in [t for t in _tries(choices) if len(t) < n_free]:  # one parameter at least stays free
            box = Bounds(lower, upper)
            values = [fixed_value(c.index, box, prior) for c in tried]
            lo, hi = lower.copy(), upper.copy()
            for c, (value, _) in zip(tried, values):
                lo[c.index] = hi[c.index] = value
            pinned = problem.variant(lower=tuple(lo), upper=tuple(hi))
            res = _refit(pinned, np.clip(current, lo, hi), local_fit, prior, max_steps, rounds)
            after = _errors(pinned, res.theta, local_fit, start)
            rise, limit = (after.rss - unc.rss) / unc.sigma2, float(scipy.stats.chi2.ppf(1.0 - level, len(tried)))
            ok = bool(np.isfinite(after.rss) and rise <= limit)
            history.append({"round": k, "fixed": [PARAM_NAMES[c.index] for c in tried], "rss_start": unc.rss,
                            "rss": after.rss, "rise_sigma2": rise, "limit": limit, "accepted": ok,
                            "n_steps": res.n_steps, "result": res.result})
            if ok:
                accepted = (tried, values, lo, hi, res.theta, after)
                break
        if accepted is None:
            break
        tried, values, lower, upper, current, unc = accepted
        fixed += [FixedParameter(PARAM_NAMES[c.index], value, c.reason, k, c.relative_se, c.partner, c.rho, source)
                  for c, (value, source) in zip(tried, values)]
    return StructureResult(
        fixed=tuple(fixed), theta_start=start, theta=current, rss_start=rss_start, rss=unc.rss,
        lower=lower, upper=upper, rounds=tuple(history), uncertainty=unc,
        settings={"local_fit": local_fit, "max_relative_se": max_relative_se, "max_correlation": max_correlation,
                  "max_rounds": max_rounds, "level": level, "prior": prior is not None})


def _tries(choices: list[_Choice]) -> list[list[_Choice]]:
    """The sets a round tries to fix, in order, the first accepted kept: every choice; the unresolved ones with the
    resolved one of largest relative bound; the unresolved ones alone (distinct, non-empty sets only)."""
    unresolved = [c for c in choices if c.unresolved]
    resolved = [c for c in choices if not c.unresolved]
    tries: list[list[_Choice]] = []
    for tried in (choices, unresolved + resolved[:1], unresolved):
        if tried and all(len(tried) != len(t) for t in tries):
            tries.append(tried)
    return tries


def _refit(
    pinned: Problem | Records, start: np.ndarray, local_fit: LocalFit, prior: Prior | None, max_steps: int,
    rounds: int,
) -> PEMResult:
    """The local fit of ``pinned`` from ``start``."""
    if local_fit == "pem":
        return pem(pinned, start=start, max_steps=max_steps, prior=prior)
    return output_error(pinned, start, rounds=rounds, max_steps=max_steps, prior=prior)


def _errors(problem: Problem | Records, theta: np.ndarray, local_fit: LocalFit, runs_at: np.ndarray) -> Uncertainty:
    """Standard errors at ``theta`` on the local fit's residuals (output error: in the runs it chooses at
    ``runs_at``, the free fit, so that every try's sum of squares is over the same runs)."""
    scored = output_error_problem(problem, runs_at) if local_fit == "output-error" else problem
    return standard_errors(scored, theta, nonfinite="unresolved")
