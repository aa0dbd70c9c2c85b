"""Frequency responses: Welch MIMO estimates from flight data, the model's own response, and the CIFER cost
between them (shared by frequency-domain identification, :mod:`jaxheli.optim.frequency_fit`, and the gap
diagnosis, :mod:`jaxheli.gap`).

The flight estimate follows the rotorcraft practice (CIFER): Welch cross-spectra over Hann-windowed,
overlapping segments, and conditioned multi-input responses ``H = Gyu Guu^-1``, so that correlated
sticks (a pilot moves several at once) are not credited to the wrong input. Each input-output pair
carries its *partial* coherence (conditioned on the other inputs), each output its *multiple* coherence
(the fraction of its power that the inputs explain linearly).

Spectra are one-sided densities in units^2/Hz with ``G[a, b] = E[X_a conj(X_b)]``; with a single input the
partial coherence is the ordinary coherence.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.signal
import scipy.stats
from jaxtyping import Bool, Complex

from ._types import Array, ArrayLike, Float, Params
from .sim.discretize import discretize
from .model import G_SI, build_ab, output_matrix

_RIDGE = 1e-9
"""Diagonal loading of the input block, relative to the strongest input at each frequency: an input
with no power there gets a zero response and zero coherence instead of a singular solve."""


class FrequencyResponse(eqx.Module):
    """Estimated frequency response from ``m`` inputs to ``k`` outputs.

    Attributes:
        freq: ``[F]`` frequencies, Hz (the Welch grid without DC).
        response: ``[F, k, m]`` complex, output units per input unit (conditioned MIMO ``Gyu Guu^-1``).
        coherence: ``[F, k, m]`` partial coherence of each pair, conditioned on the other inputs, in [0, 1].
        multiple_coherence: ``[F, k]`` multiple coherence of each output with all inputs, in [0, 1].
        output_power: ``[F, k]`` output auto-spectral density, units^2/Hz.
        averages: effective number of independent Welch averages (overlap accounted for).
    """

    freq: Float[Array, " F"]
    response: Complex[Array, "F k m"]
    coherence: Float[Array, "F k m"]
    multiple_coherence: Float[Array, "F k"]
    output_power: Float[Array, "F k"]
    averages: float = eqx.field(static=True)

    def null_mean(self) -> float:
        """Expected multiple coherence of an output unrelated to the inputs, ``m / n`` (the estimate's bias)."""
        return self.response.shape[-1] / self.averages

    def thresholds(self, level: float = 0.95) -> tuple[float, float]:
        """``(partial, multiple)`` coherence that uncorrelated signals exceed with probability ``1 - level``
        in one bin (null laws Beta(1, n - m) and Beta(m, n - m), ``n`` the effective averages)."""
        m = self.response.shape[-1]
        n = self.averages
        return float(scipy.stats.beta.ppf(level, 1, n - m)), float(scipy.stats.beta.ppf(level, m, n - m))


def _welch_plan(n: int, dt: float, segment_seconds: float, overlap: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Segment starts ``[S]``, periodic Hann window ``[L]`` and effective number of averages for ``n``
    samples at ``dt`` s in segments of ``segment_seconds`` s overlapping by the fraction ``overlap``."""
    if not 0.0 <= overlap < 1.0:
        raise ValueError(f"welch: overlap must be in [0, 1), got {overlap}")
    length = int(round(segment_seconds / dt))
    if length < 8 or length > n:
        raise ValueError(
            f"welch: segment_seconds={segment_seconds} gives {length} samples; need 8 <= samples <= record ({n})"
        )
    step = max(1, length - int(round(overlap * length)))
    starts = np.arange(0, n - length + 1, step)
    window = scipy.signal.get_window("hann", length)
    count = starts.size
    lags = np.arange(1, count)
    shifted = [np.sum(window[: length - j * step] * window[j * step:]) if j * step < length else 0.0 for j in lags]
    rho = (np.asarray(shifted, dtype=np.float64) / np.sum(window**2)) ** 2
    averages = count / (1.0 + 2.0 * np.sum((1.0 - lags / count) * rho))
    return starts, window, float(averages)


@jax.jit
def _spectral_matrix(x: Float[Array, "N c"], window: Float[Array, " L"], starts: Array, dt: float) -> Array:
    """One-sided Welch spectral matrix ``[F, c, c]`` (all rfft bins), ``G[a, b] = E[X_a conj(X_b)]``."""
    length = window.shape[0]
    segs = x[starts[:, None] + jnp.arange(length)[None, :]]
    segs = (segs - jnp.mean(segs, axis=1, keepdims=True)) * window[None, :, None]
    X = jnp.fft.rfft(segs, axis=1)
    G = jnp.einsum("sfa,sfb->fab", X, jnp.conj(X)) / starts.shape[0]
    scale = jnp.full(X.shape[1], 2.0 * dt / jnp.sum(window**2)).at[0].multiply(0.5)
    if length % 2 == 0:
        scale = scale.at[-1].multiply(0.5)
    return G * scale[:, None, None]


@functools.partial(jax.jit, static_argnums=1)
def _conditioned(G: Complex[Array, "F c c"], m: int) -> tuple[Array, Array, Array, Array]:
    """Response, partial and multiple coherence and output power from the spectral matrix (inputs first).

    One inverse ``P`` of each augmented ``[u, y_i]`` matrix gives all three: ``H = -P_yu / P_yy``,
    multiple coherence ``1 - 1 / (G_yy P_yy)`` and partial coherence ``|P_jy|^2 / (P_jj P_yy)`` (Dahlhaus).
    """
    Guu, Gyu = G[:, :m, :m], G[:, m:, :m]
    Gyy = jnp.real(jnp.diagonal(G[:, m:, m:], axis1=1, axis2=2))
    k = Gyy.shape[1]
    ridge = _RIDGE * jnp.max(jnp.real(jnp.diagonal(Guu, axis1=1, axis2=2)), axis=1)
    Guu = Guu + ridge[:, None, None] * jnp.eye(m)[None]
    live = Gyy > 0
    safe_yy = jnp.where(live, Gyy, 1.0)
    top = jnp.concatenate([jnp.broadcast_to(Guu[:, None], (Guu.shape[0], k, m, m)),
                           jnp.conj(Gyu)[..., :, None]], axis=-1)
    bottom = jnp.concatenate([Gyu[..., None, :], safe_yy[..., None, None].astype(Gyu.dtype)], axis=-1)
    P = jnp.linalg.inv(jnp.concatenate([top, bottom], axis=-2))
    Pyy = jnp.real(P[..., m, m])
    H = -P[..., m, :m] / Pyy[..., None]
    multiple = 1.0 - 1.0 / (safe_yy * Pyy)
    Puu = jnp.real(jnp.diagonal(P[..., :m, :m], axis1=-2, axis2=-1))
    partial = jnp.abs(P[..., :m, m]) ** 2 / (Puu * Pyy[..., None])
    partial = jnp.where(live[..., None] & jnp.isfinite(partial), jnp.clip(partial, 0.0, 1.0), 0.0)
    multiple = jnp.where(live & jnp.isfinite(multiple), jnp.clip(multiple, 0.0, 1.0), 0.0)
    return H, partial, multiple, Gyy


def estimate_frequency_response(
    inputs: Float[ArrayLike, "N m"],
    outputs: Float[ArrayLike, "N k"],
    dt: float,
    *,
    segment_seconds: float | None = None,
    overlap: float = 0.5,
) -> FrequencyResponse:
    """Welch MIMO frequency response from ``inputs`` to ``outputs`` sampled every ``dt`` s.

    Args:
        inputs: ``[N, m]`` input records (sticks); correlated inputs are separated by conditioning.
        outputs: ``[N, k]`` output records (measured outputs, or residuals).
        dt: sample time, s.
        segment_seconds: Welch segment length, s (frequency resolution ``1 / segment_seconds`` Hz); default
            :func:`default_segment`.
        overlap: fraction of a segment shared with the next (0.5: Hann at 50 %).
    """
    u = jnp.asarray(inputs, dtype=jnp.float64)
    y = jnp.asarray(outputs, dtype=jnp.float64)
    if u.ndim != 2 or y.ndim != 2 or u.shape[0] != y.shape[0]:
        raise ValueError(
            f"estimate_frequency_response: need inputs [N, m] and outputs [N, k]; got {u.shape}, {y.shape}"
        )
    if not (jnp.all(jnp.isfinite(u)) and jnp.all(jnp.isfinite(y))):
        raise ValueError("estimate_frequency_response: inputs and outputs must be finite")
    if dt <= 0:
        raise ValueError(f"estimate_frequency_response: dt must be > 0 s, got {dt}")
    n, m = u.shape
    seconds = default_segment(n, dt) if segment_seconds is None else segment_seconds
    starts, window, averages = _welch_plan(n, dt, seconds, overlap)
    if averages <= m + 1:
        raise ValueError(
            f"estimate_frequency_response: {averages:.3g} effective averages for {m} inputs; shorten "
            f"segment_seconds ({seconds} s) or use a longer record ({n * dt:.4g} s)"
        )
    G = _spectral_matrix(jnp.concatenate([u, y], axis=1), jnp.asarray(window), jnp.asarray(starts), dt)
    H, partial, multiple, Gyy = _conditioned(G[1:], m)
    freq = jnp.fft.rfftfreq(window.size, dt)[1:]
    return FrequencyResponse(freq, H, partial, multiple, Gyy, averages)


def residual_frequency_response(
    inputs: Float[ArrayLike, "N m"],
    measured: Float[ArrayLike, "N k"],
    simulated: Float[ArrayLike, "N k"],
    dt: float,
    **welch,
) -> FrequencyResponse:
    """Input-to-residual response ``measured - simulated``: high coherence means the residual is driven by
    the inputs (missing model structure), low coherence means disturbance or noise. ``welch``: the segment
    options of :func:`estimate_frequency_response`."""
    residual = jnp.asarray(measured, dtype=jnp.float64) - jnp.asarray(simulated, dtype=jnp.float64)
    return estimate_frequency_response(inputs, residual, dt, **welch)


def default_segment(n: int, dt: float, longest: float = 10.0) -> float:
    """Welch segment length, s: ``longest`` s, shortened so a record of ``n`` samples holds >= 12 segments at
    50 % overlap (fewer averages leave four-input coherence too biased to read)."""
    return min(longest, (2 * n // 13) * dt)


def model_frequency_response(
    theta: Params,
    freq: Float[ArrayLike, " F"],
    outputs: tuple[str, ...] | list[str],
    g: float = G_SI,
    dt: float | None = None,
) -> Complex[Array, "*batch F k 4"]:
    """Model frequency response ``C (j w I - A)^-1 B`` at ``freq`` (Hz) from the four sticks to ``outputs``.

    ``theta[..., 40]`` may carry any batch (vmappable, differentiable). With ``dt`` (s) the response is
    that of the zero-order-hold discretisation the simulator runs, ``C (e^{j w dt} I - Ad)^-1 Bd``.
    """
    return _model_response(jnp.asarray(theta), jnp.asarray(freq), tuple(outputs), float(g), dt)


@eqx.filter_jit
def _model_response(theta: Array, freq: Array, outputs: tuple[str, ...], g: float, dt: float | None) -> Array:
    A, B = build_ab(theta, g)
    if dt is not None:
        d = discretize(A, B, dt, "zoh")
        A, B = d.Ad, d.B0
    f = jnp.asarray(freq, dtype=A.dtype)
    w = 2j * jnp.pi * f
    s = jnp.exp(w * dt) if dt is not None else w
    batch = A.shape[:-2]
    n = A.shape[-1]
    s = s.reshape((1,) * len(batch) + (-1, 1, 1))
    M = s * jnp.eye(n).reshape((1,) * (len(batch) + 1) + (n, n)) - A[..., None, :, :]
    Bf = jnp.broadcast_to(B[..., None, :, :], M.shape[:-1] + B.shape[-1:]).astype(M.dtype)
    X = jnp.linalg.solve(M, Bf)
    C = output_matrix(outputs).astype(M.dtype)
    return jnp.einsum("ks,...fsm->...fkm", C, X)


def mismatch(
    estimate: FrequencyResponse,
    model: Complex[ArrayLike, "F k m"],
    *,
    min_coherence: float = 0.6,
    band: tuple[float, float] = (0.0, 5.0),
) -> dict[str, Float[np.ndarray, "k m"]]:
    """Flight against model response per pair over the bins in ``band`` (Hz, the flight-dynamics range;
    above it rotor vibration can be coherent too) where the partial coherence is at least
    ``min_coherence``: ``bins`` used, mean magnitude error (dB, model over flight), mean absolute phase
    error (deg) and the CIFER cost ``J = 20 mean[W_g (dB error)^2 + 0.01745 (deg error)^2]`` with coherence
    weight ``(1.58 (1 - exp(-gamma^2)))^2``, ``gamma^2`` the partial coherence (``J <= 100``: acceptable,
    ``<= 50``: excellent, :func:`cifer_cost`); NaN where no bin qualifies."""
    H = np.asarray(estimate.response)
    Hm = np.asarray(model)
    if Hm.shape != H.shape:
        raise ValueError(f"mismatch: model response {Hm.shape} does not match the estimate {H.shape}")
    gamma = np.asarray(estimate.coherence)
    f = np.asarray(estimate.freq)[:, None, None]
    use = (gamma >= min_coherence) & (f >= band[0]) & (f <= band[1])
    mag, phase = (np.asarray(e) for e in response_errors(np.where(use, Hm, 1.0), np.where(use, H, 1.0)))
    bins = use.sum(axis=0)
    den = np.where(bins > 0, bins, np.nan)
    return {
        "bins": bins,
        "magnitude_db": np.where(use, mag, 0.0).sum(axis=0) / den,
        "phase_deg": np.where(use, np.abs(phase), 0.0).sum(axis=0) / den,
        "cifer_j": np.asarray(cifer_cost(Hm, H, gamma, use)),
    }


_FLOOR_DB = -200.0
"""Magnitude error, dB, below which a model response counts as zero."""

W_PHASE = 0.01745
"""CIFER's phase weight against the magnitude's (``W_g = 1``): 1 deg of phase error weighs as 0.132 dB."""


def coherence_weight(coherence: Float[ArrayLike, "*shape"]) -> Float[Array, "*shape"]:
    """CIFER's weight ``(1.58 (1 - exp(-gamma^2)))^2`` of a bin with partial coherence ``gamma^2`` (~1 at 1)."""
    return (1.58 * (1.0 - jnp.exp(-jnp.asarray(coherence)))) ** 2


def response_errors(
    model: Complex[ArrayLike, "*shape"], flight: Complex[ArrayLike, "*shape"]
) -> tuple[Float[Array, "*shape"], Float[Array, "*shape"]]:
    """Magnitude error ``20 log10 |model / flight|`` (dB) and phase error ``angle(model / flight)`` (deg, wrapped
    into (-180, 180]); differentiable in ``model`` (``flight`` must be non-zero). A model response of zero reads
    as :data:`_FLOOR_DB` with phase error 0 (finite, zero gradient)."""
    ratio = jnp.asarray(model) / jnp.asarray(flight)
    re, im = jnp.real(ratio), jnp.imag(ratio)
    power = re**2 + im**2
    live = power > 10.0 ** (_FLOOR_DB / 10.0)
    mag = 10.0 * jnp.log10(jnp.where(live, power, 10.0 ** (_FLOOR_DB / 10.0)))
    phase = jnp.degrees(jnp.arctan2(jnp.where(live, im, 0.0), jnp.where(live, re, 1.0)))
    return mag, phase


def cifer_residuals(
    model: Complex[ArrayLike, "F k m"],
    flight: Complex[ArrayLike, "F k m"],
    coherence: Float[ArrayLike, "F k m"],
    use: Bool[ArrayLike, "F k m"],
) -> Float[Array, "2 F k m"]:
    """Residuals whose squares sum (over the first two axes) to Tischler's cost of each pair,
    ``J = 20 / n_w sum_w W_gamma [(dB error)^2 + W_PHASE (deg error)^2]`` over the ``n_w`` bins in ``use``
    (:func:`response_errors`, :func:`coherence_weight`); zero off ``use``."""
    use = jnp.asarray(use)
    n = jnp.sum(use, axis=0)
    w = jnp.where(use, 20.0 * coherence_weight(coherence) / jnp.maximum(n, 1)[None], 0.0)
    mag, phase = response_errors(jnp.where(use, model, 1.0), jnp.where(use, flight, 1.0))
    return jnp.stack([jnp.sqrt(w) * mag, jnp.sqrt(w * W_PHASE) * phase])


def cifer_cost(
    model: Complex[ArrayLike, "F k m"],
    flight: Complex[ArrayLike, "F k m"],
    coherence: Float[ArrayLike, "F k m"],
    use: Bool[ArrayLike, "F k m"],
) -> Float[Array, "k m"]:
    """Tischler's cost ``J`` of each (output, input) pair over the bins in ``use`` (:func:`cifer_residuals`);
    NaN for a pair without a bin. ``J <= 100``: acceptable, ``<= 50``: excellent."""
    J = jnp.sum(cifer_residuals(model, flight, coherence, use) ** 2, axis=(0, 1))
    return jnp.where(jnp.any(jnp.asarray(use), axis=0), J, jnp.nan)
