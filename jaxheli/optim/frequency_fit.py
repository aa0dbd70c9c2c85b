"""Frequency-domain identification as CIFER does it: fit the model's frequency responses to the flight's.

The flight's responses are the conditioned MIMO Welch estimates (:func:`jaxheli.spectra.estimate_frequency_response`,
sticks to the scored channels, each pair with its partial coherence ``gamma^2``). Every (input, output) pair with
at least ``min_bins`` bins in ``band`` where ``gamma^2 >= min_coherence`` is fitted over those bins with Tischler's
cost (:func:`jaxheli.spectra.cifer_cost`)::

    J = 20 / n_w sum_w W_gamma [W_g (|Tc|_dB - |T|_dB)^2 + W_p (phase_c - phase)^2]
    W_g = 1, W_p = 0.01745 (deg), W_gamma = (1.58 (1 - exp(-gamma^2)))^2, phase error wrapped to (-180, 180]

(``J <= 100`` per pair: acceptable, ``<= 50``: excellent). Levenberg-Marquardt minimises the sum of the pairs'
``J`` as least squares on :func:`jaxheli.spectra.cifer_residuals`, in the unit coordinates of the bounds with
the engines' penalty past a bound and margin (:mod:`jaxheli.optim.boxed_lm`), from ``starts`` points, one after
another in one compiled program (``lax.map``: vmapped, every step of the batched starts costs more than the steps
alone, and the starts that converged early wait for the last): the given start, if
any, and the best of many points drawn uniformly in the box (scoring ``J`` needs no simulation, so thousands cost
seconds; the box's middle is a poor start: every control derivative is 0 there). The lowest
average ``J`` wins. From the authors' wide box most starts still end in local minima (phase wrapping, the yaw
feedback loop): use several, a narrower box, or the time-domain polish afterwards.

The model response is the simulator's: ZOH discretisation at the record's sample time (continuous under FOH).
An unstable hover model has a response as well defined as a stable one's, so no restart is needed; initial
state and trim offsets do not reach the spectra, and are left to a time-domain polish.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Complex

from .._types import Array, ArrayLike, Bool, Float
from .._xla import quick_jit
from ..bounds import Bounds, Free
from ..data.flight import FlightData
from ..model import INPUT_NAMES, PARAM_NAMES
from ..problem import Problem, Records, as_problem, parts
from ..spectra import cifer_cost, cifer_residuals, default_segment, estimate_frequency_response
from ..spectra import model_frequency_response
from .boxed_lm import FreeAxes, Solver, boxed_least_squares, least_squares_solver
from .pem import start_vector

MIN_COHERENCE = 0.6
"""Partial coherence ``gamma^2`` a bin needs to be fitted (CIFER's usual threshold)."""

ACCEPTABLE_J = 100.0
"""Average ``J`` at or below which a fit is acceptable (Tischler & Remple; ``<= 50``: excellent)."""

STARTS = 4
"""Default number of Levenberg-Marquardt starts: from an IWO start, 4 starts of up to :data:`MAX_STEPS` steps reach
the same average ``J``, and the polish after them the same model, as 8 starts of up to 200 steps, in about a third
of the time."""

MAX_STEPS = 100
"""Default Levenberg-Marquardt step limit of each start (:data:`STARTS`)."""


class IncoherentFlight(ValueError):
    """No input-output pair of a record is coherent enough over enough bins to fit frequency responses."""


def default_band(dt: float) -> tuple[float, float]:
    """Fitted band, Hz: 0.1 Hz to a third of the Nyquist frequency of ``dt`` s, at most 10 Hz."""
    return 0.1, min(10.0, 1.0 / (6.0 * dt))


def model_step(hold: str, dt: float) -> float | None:
    """Sample time, s, of the model response that matches the simulator under ``hold`` (``None``: continuous)."""
    return dt if hold == "zoh" else None


class FrequencyTarget(eqx.Module):
    """One record's flight responses on the fitted bins, and how the model's is computed.

    Attributes:
        freq: ``[F]`` bins in the band, Hz.
        response: ``[F, k, m]`` flight response, output units per stick.
        coherence: ``[F, k, m]`` partial coherence ``gamma^2``.
        use: ``[F, k, m]`` bins fitted (coherent enough, of a pair with enough such bins).
        outputs, g, dt: the model response's channels, gravity and sample time (``None``: continuous).
    """

    freq: Float[Array, " F"]
    response: Complex[Array, "F k m"]
    coherence: Float[Array, "F k m"]
    use: Bool[Array, "F k m"]
    outputs: tuple[str, ...] = eqx.field(static=True)
    g: float = eqx.field(static=True)
    dt: float | None = eqx.field(static=True)

    def model(self, theta: Float[Array, "40"]) -> Complex[Array, "F k m"]:
        """The model's response on the bins."""
        return model_frequency_response(theta, self.freq, self.outputs, self.g, self.dt)

    def residuals(self, theta: Float[Array, "40"]) -> Float[Array, " r"]:
        """Residuals whose sum of squares is the sum of the fitted pairs' ``J``."""
        return cifer_residuals(self.model(theta), self.response, self.coherence, self.use).ravel()

    def costs(self, theta: Float[Array, "40"]) -> Float[Array, "k m"]:
        """``J`` of each pair (NaN for a pair not fitted)."""
        return cifer_cost(self.model(theta), self.response, self.coherence, self.use)

    def pairs(self) -> list[tuple[int, int]]:
        """``(output, input)`` indices of the fitted pairs."""
        return [tuple(map(int, p)) for p in np.argwhere(np.asarray(self.use).any(axis=0))]


def frequency_target(
    problem: Problem,
    *,
    band: tuple[float, float] | None = None,
    min_coherence: float = MIN_COHERENCE,
    min_bins: int = 10,
    segment_seconds: float | None = None,
    pairs: Sequence[tuple[str, str]] | None = None,
) -> FrequencyTarget:
    """The :class:`FrequencyTarget` of one record (its sticks to its scored channels): ``band`` in Hz (default
    :func:`default_band`), bins with ``gamma^2 >= min_coherence`` of pairs with at least ``min_bins`` of them
    (a weak off-axis coupling coherent in a few bins only is unreliable: on a 40-s synthetic flight, lat->w with
    7 such bins had ``J`` ~ 4000 at the truth), only ``(input, output)`` ``pairs`` if given; Welch segments of
    ``segment_seconds`` s (default :func:`jaxheli.spectra.default_segment`)."""
    lo, hi = default_band(problem.dt) if band is None else band
    est = estimate_frequency_response(problem.sim.inputs, problem.target, problem.dt,
                                      segment_seconds=segment_seconds)
    f = np.asarray(est.freq)
    keep = (f >= lo) & (f <= hi)
    coherence = np.asarray(est.coherence)[keep]
    use = coherence >= min_coherence
    use &= use.sum(axis=0, keepdims=True) >= min_bins
    if pairs is not None:
        use &= np.array([[(i, o) in pairs for i in INPUT_NAMES] for o in problem.outputs])[None]
    if not use.any():
        named = "" if pairs is None else " of " + str(pairs)
        raise IncoherentFlight(f"{problem.source}: no (input, output) pair{named} has {min_bins} bins in "
                               f"{lo:g}-{hi:.3g} Hz with coherence >= {min_coherence}; excite the sticks more, lower "
                               f"min_coherence or widen band")
    return FrequencyTarget(jnp.asarray(f[keep]), jnp.asarray(est.response)[keep], jnp.asarray(coherence),
                           jnp.asarray(use), problem.outputs, problem.settings.g,
                           model_step(problem.settings.hold, problem.dt))


def frequency_targets(problem: Problem | Records, **options: Any) -> tuple[FrequencyTarget, ...]:
    """Each record's :func:`frequency_target` (``options``: its keywords)."""
    return tuple(frequency_target(part, **options) for part in parts(problem))


def cifer_report(targets: tuple[FrequencyTarget, ...], theta: Float[ArrayLike, "40"]) -> dict[str, Any]:
    """``J`` of every fitted pair at ``theta`` (``"lat->p"``, with ``" (record 2)"`` ... for further records), their
    bins, the average ``J`` and whether it is acceptable (``<= 100``)."""
    j, bins = {}, {}
    for r, target in enumerate(targets):
        costs = np.asarray(target.costs(jnp.asarray(theta)))
        counts = np.asarray(target.use).sum(axis=0)
        for k, m in target.pairs():
            name = f"{INPUT_NAMES[m]}->{target.outputs[k]}" + (f" (record {r + 1})" if r else "")
            j[name], bins[name] = float(costs[k, m]), int(counts[k, m])
    average = float(np.mean(list(j.values())))
    return {"j": j, "bins": bins, "j_average": average, "acceptable": bool(average <= ACCEPTABLE_J)}


def average_j(targets: tuple[FrequencyTarget, ...], theta: Array) -> Array:
    """Mean ``J`` over every record's fitted pairs (``inf`` when one is not finite)."""
    j = jnp.concatenate([t.costs(theta).ravel() for t in targets])
    fitted = jnp.concatenate([jnp.any(t.use, axis=0).ravel() for t in targets])
    mean = jnp.sum(jnp.where(fitted, j, 0.0)) / jnp.sum(fitted)
    return jnp.where(jnp.isfinite(mean), mean, jnp.inf)


_Fitted = tuple[tuple[FrequencyTarget, ...], FreeAxes]
"""The records' responses and the parameters the solver moves."""


def _residual(v: Array, fitted: _Fitted) -> Array:
    targets, axes = fitted
    theta = axes.theta(v)
    return jnp.concatenate([t.residuals(theta) for t in targets])


def _score(v0: Array, v: Array, fitted: _Fitted) -> tuple[Array, tuple[Array, Array]]:
    """Average ``J`` at the start ``v0`` and at the answer ``v`` clipped into the box (``[2]``), and their
    parameters."""
    targets, axes = fitted
    thetas = axes.theta(v0), axes.theta(Bounds.clip_unit(v))
    return jnp.stack([average_j(targets, th) for th in thetas]), thetas


@eqx.filter_jit
def _screen(fitted: _Fitted, v: Float[Array, "S n"]) -> Float[Array, " S"]:
    """Average ``J`` of each row of unit coordinates."""
    targets, axes = fitted
    return jax.lax.map(lambda x: average_j(targets, axes.theta(x)), v, batch_size=250)


@quick_jit
def _solve(
    fitted: _Fitted, v0: Float[Array, "K n"], solver: optx.AbstractLeastSquaresSolver, max_steps: int
) -> tuple[Array, Array, Array, Array, Array]:
    """One least-squares solve per start, one after another; each keeps its start unless the solver lowered the
    average ``J``. Returns ``theta [K, 40]``, average ``J`` at the start and the end ``[K]``, steps and success
    ``[K]``."""

    def one(v):
        sol = boxed_least_squares(_residual, solver, v, fitted, max_steps, _score)
        return sol.kept(*sol.aux), sol.loss[0], sol.kept(*sol.loss), sol.num_steps, sol.successful

    return jax.lax.map(one, v0)


@dataclasses.dataclass(frozen=True)
class FrequencyFitResult:
    """Outcome of :func:`frequency_fit`.

    Attributes:
        theta: ``[40]`` the best start's answer (physical units).
        theta_start: ``[40]`` the start it came from.
        free: names of the fitted parameters.
        j: ``J`` per fitted pair at ``theta`` (:func:`cifer_report`); ``bins``: its fitted bins.
        j_average: mean ``J`` over the pairs (``<= 100``: acceptable).
        start_j, final_j: ``[K]`` average ``J`` of every start, before and after its solve.
        n_steps, success: ``[K]`` solver steps and convergence of every start.
        settings: band, coherence threshold, Welch segment, starts, solver settings.
        targets: each record's fitted flight responses (for :func:`cifer_report` of other parameters; not in
            :meth:`to_dict`).
    """

    theta: np.ndarray
    theta_start: np.ndarray
    free: tuple[str, ...]
    j: dict[str, float]
    bins: dict[str, int]
    j_average: float
    start_j: np.ndarray
    final_j: np.ndarray
    n_steps: np.ndarray
    success: np.ndarray
    settings: dict[str, Any]
    targets: tuple[FrequencyTarget, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values; parameter vectors as ``{name: value}``."""
        return {
            "theta": dict(zip(PARAM_NAMES, self.theta.tolist())),
            "theta_start": dict(zip(PARAM_NAMES, self.theta_start.tolist())),
            "free": list(self.free), "j": self.j, "bins": self.bins, "j_average": self.j_average,
            "acceptable": bool(self.j_average <= ACCEPTABLE_J), "start_j": self.start_j.tolist(),
            "final_j": self.final_j.tolist(), "n_steps": self.n_steps.tolist(), "success": self.success.tolist(),
            "settings": self.settings,
        }


def frequency_fit(
    data: FlightData | Problem | Records,
    *,
    start: Float[ArrayLike, "40"] | None = None,
    starts: int = STARTS,
    screen: int = 2000,
    seed: int = 0,
    band: tuple[float, float] | None = None,
    min_coherence: float = MIN_COHERENCE,
    min_bins: int = 10,
    segment_seconds: float | None = None,
    pairs: Sequence[tuple[str, str]] | None = None,
    solver: Solver = "lm",
    max_steps: int = MAX_STEPS,
    free: Free = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    **settings: Any,
) -> FrequencyFitResult:
    """Fit the hover model to a record's frequency responses (see the module).

    Args:
        data: a flight (with :class:`~jaxheli.problem.Settings` fields in ``settings``: ``outputs``, ``hold``,
            ``g``, ``lower``/``upper``), several, or a :class:`~jaxheli.problem.Problem` /
            :class:`~jaxheli.problem.Records` (each record its own responses; the pairs' ``J`` add).
        start: the first start ``theta[40]`` (default: every start drawn); the non-free axes stay at it (default:
            the middle of the box, the pinned values).
        starts: number of starts ``K``, solved in one program: ``start`` if given, and the best (lowest average
            ``J``) of ``screen`` points drawn uniformly in the box from ``seed`` (one cheap vmapped scoring).
        band, min_coherence, min_bins, segment_seconds, pairs: the fitted bins (:func:`frequency_target`).
        solver, max_steps, free, rtol, atol: as in :func:`jaxheli.optim.pem.pem`.
    """
    if starts < 1:
        raise ValueError(f"frequency_fit: starts must be >= 1, got {starts}")
    problem = as_problem(data, None, **settings)
    targets = frequency_targets(problem, band=band, min_coherence=min_coherence, min_bins=min_bins,
                                segment_seconds=segment_seconds, pairs=pairs)
    bounds = problem.bounds
    base, mask = start_vector(start, bounds), bounds.free_mask(free)
    axes = FreeAxes(bounds, base, mask)
    v0 = axes.start()[None][: int(start is not None)]
    wanted = starts - v0.shape[0]
    if wanted:
        drawn = jax.random.uniform(jax.random.PRNGKey(seed), (max(screen, wanted), v0.shape[1]), v0.dtype)
        v0 = jnp.concatenate([v0, drawn[jnp.argsort(_screen((targets, axes), drawn))[:wanted]]])
    theta, j0, j1, steps, ok = (np.asarray(a) for a in _solve(
        (targets, axes), v0, least_squares_solver(solver, rtol, atol, v0.shape[1]), int(max_steps)))
    best = int(np.argmin(j1))
    report = cifer_report(targets, theta[best])
    part = parts(problem)[0]
    lo, hi = default_band(part.dt) if band is None else band
    return FrequencyFitResult(
        theta=theta[best],
        theta_start=np.asarray(axes.theta(v0[best])),
        free=tuple(n for n, m in zip(PARAM_NAMES, mask) if m),
        j=report["j"], bins=report["bins"], j_average=report["j_average"],
        start_j=j0, final_j=j1, n_steps=steps, success=ok,
        settings={"band_hz": [float(lo), float(hi)], "min_coherence": min_coherence, "min_bins": min_bins,
                  "pairs": None if pairs is None else [list(p) for p in pairs],
                  "segment_s": [default_segment(p.n_samples, p.dt) if segment_seconds is None else segment_seconds
                                for p in parts(problem)],
                  "starts": starts, "screen": screen, "seed": seed, "solver": solver, "max_steps": int(max_steps),
                  "rtol": rtol, "atol": atol, "model_dt": targets[0].dt},
        targets=targets,
    )
