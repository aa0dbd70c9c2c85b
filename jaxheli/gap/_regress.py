"""Least squares with standard errors that survive autocorrelated residuals (Newey-West, Bartlett kernel).

Flight-test regressions run on low-passed signals, so neighbouring residuals are far from independent and
ordinary least-squares standard errors are too small by a factor of ten or more. The heteroscedasticity-
and autocorrelation-consistent covariance below widens them by the residual's own correlation.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from jaxtyping import Float


@dataclasses.dataclass(frozen=True)
class RegressionFit:
    """A linear fit ``y ~ X beta``: coefficients, their 1-sigma covariance, residual and kernel bandwidth."""

    beta: Float[np.ndarray, "m"]
    cov: Float[np.ndarray, "m m"]
    residual: Float[np.ndarray, "N"]
    bandwidth: int

    @property
    def se(self) -> Float[np.ndarray, "m"]:
        """1-sigma standard errors of ``beta``."""
        return np.sqrt(np.diag(self.cov))


def well_posed(X: Float[np.ndarray, "N m"], rcond: float = 1e-8) -> bool:
    """True when the columns of ``X`` are finite, not constant zero and not collinear."""
    if not np.all(np.isfinite(X)) or X.shape[0] <= X.shape[1]:
        return False
    norms = np.linalg.norm(X, axis=0)
    if np.any(norms == 0):
        return False
    s = np.linalg.svd(X / norms, compute_uv=False)
    return bool(s[-1] > rcond * s[0])


def hac_lstsq(y: Float[np.ndarray, "N"], X: Float[np.ndarray, "N m"], min_bandwidth: int = 1) -> RegressionFit:
    """Ordinary least squares with the Newey-West covariance.

    The Bartlett bandwidth is twice the lag at which the residual autocorrelation first falls below 0.1,
    at least ``min_bandwidth`` samples (e.g. the low-pass filter's memory) and at most ``N / 4``.
    """
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    e = y - X @ beta
    n = e.size
    bandwidth = int(min(n // 4, max(min_bandwidth, 2 * _decorrelation_lag(e))))
    meat = _bartlett_meat(X * e[:, None], bandwidth)
    bread = np.linalg.inv(X.T @ X)
    cov = bread @ meat @ bread
    return RegressionFit(beta=beta, cov=0.5 * (cov + cov.T), residual=e, bandwidth=bandwidth)


def _bartlett_meat(score: Float[np.ndarray, "N m"], bandwidth: int) -> Float[np.ndarray, "m m"]:
    """``sum_|k|<=B (1 - |k| / (B + 1)) sum_t score[t + k]^T score[t]``, evaluated in the frequency domain
    (zero-padded to ``2 N``, so no wrap-around): the kernel's transform weights the score's periodogram."""
    n = score.shape[0]
    size = 2 * n
    kernel = np.zeros(size)
    kernel[: bandwidth + 1] = 1.0 - np.arange(bandwidth + 1) / (bandwidth + 1)
    kernel[size - bandwidth:] = kernel[1: bandwidth + 1][::-1]
    spectrum = np.fft.rfft(score, size, axis=0)
    weight = np.fft.rfft(kernel).real
    weight[1:-1] *= 2.0  # the half spectrum stands for both signs of frequency
    re, im = spectrum.real, spectrum.imag
    return ((re * weight[:, None]).T @ re + (im * weight[:, None]).T @ im) / size


def _decorrelation_lag(e: Float[np.ndarray, "N"], threshold: float = 0.1) -> int:
    """First lag (samples) at which the autocorrelation of ``e`` drops below ``threshold``."""
    e = e - e.mean()
    n = e.size
    spectrum = np.fft.rfft(e, 2 * n)
    acf = np.fft.irfft(np.abs(spectrum) ** 2)[:n]
    if acf[0] <= 0:
        return 1
    below = np.flatnonzero(acf / acf[0] < threshold)
    return int(below[0]) if below.size else n
