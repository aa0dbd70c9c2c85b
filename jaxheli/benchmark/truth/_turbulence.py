"""Dryden turbulence of MIL-F-8785C (low altitude) on ``u v w p q``: shaping filters driven by white noise.

The air mass is frozen and carried past the hovering helicopter by a mean wind ``V`` (Taylor's hypothesis), so the
spatial spectra become temporal ones at that speed. The catalogue's candidate is a first-order Gauss-Markov gust
on ``u v w`` with one std and time constant; here ``v`` and ``w`` are second order, the scales differ per axis and
the rotor disc sees rate gusts.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.signal

FOOT = 0.3048
"""m per ft (the standard's low-altitude formulas are in feet)."""


@dataclasses.dataclass(frozen=True)
class Dryden:
    """Low-altitude Dryden turbulence: ``w20`` wind speed at 20 ft (m/s; ``sigma_w = 0.1 w20``), ``altitude`` (m),
    mean wind ``speed`` (m/s) carrying it past and the rotor ``span`` (m, the standard's wing span)."""

    w20: float
    altitude: float
    speed: float
    span: float

    def sigmas(self) -> tuple[float, float, float]:
        """``(sigma_u, sigma_v, sigma_w)`` (m/s): ``sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4``."""
        h = self.altitude / FOOT
        sigma_w = 0.1 * self.w20
        sigma_u = sigma_w / (0.177 + 0.000823 * h) ** 0.4
        return sigma_u, sigma_u, sigma_w

    def scales(self) -> tuple[float, float, float]:
        """``(L_u, L_v, L_w)`` (m): ``L_u = L_v = h / (0.177 + 0.000823 h)^1.2``, ``L_w = h`` (``h`` in ft)."""
        h = self.altitude / FOOT
        horizontal = h / (0.177 + 0.000823 * h) ** 1.2 * FOOT
        return horizontal, horizontal, self.altitude

    def filters(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Numerator and denominator (descending powers of ``s``) of the shaping filters of ``u v w p q``: unit
        white noise of one-sided PSD 1 in rad/s in, a gust of one-sided PSD ``Phi(omega)`` out."""
        (su, sv, sw), (lu, lv, lw), V, b = self.sigmas(), self.scales(), self.speed, self.span
        tu, tv, tw = lu / V, lv / V, lw / V
        hu = (np.array([su * np.sqrt(2.0 * tu / np.pi)]), np.array([tu, 1.0]))
        hv = (sv * np.sqrt(tv / np.pi) * np.array([np.sqrt(3.0) * tv, 1.0]), np.polymul([tv, 1.0], [tv, 1.0]))
        hw = (sw * np.sqrt(tw / np.pi) * np.array([np.sqrt(3.0) * tw, 1.0]), np.polymul([tw, 1.0], [tw, 1.0]))
        tp = 4.0 * b / (np.pi * V)
        gain_p = sw * np.sqrt(0.8 / V) * (np.pi / (4.0 * b)) ** (1.0 / 6.0) / lw ** (1.0 / 3.0)
        hp = (np.array([gain_p]), np.array([tp, 1.0]))
        hq = (np.polymul([1.0 / V, 0.0], hw[0]), np.polymul([tp, 1.0], hw[1]))
        return [hu, hv, hw, hp, hq]

    def psd(self, omega: np.ndarray) -> np.ndarray:
        """MIL-F-8785C one-sided PSDs ``[len(omega), 3]`` of ``u v w`` (m^2/s^2 per rad/s) at ``omega`` (rad/s),
        ``sigma^2 = integral_0^inf Phi d omega``."""
        out = []
        for sigma, scale in zip(self.sigmas(), self.scales()):
            x = (scale * omega / self.speed) ** 2
            out.append(sigma**2 * scale / (np.pi * self.speed) * (1.0 + 3.0 * x) / (1.0 + x) ** 2)
        su, lu = self.sigmas()[0], self.scales()[0]
        out[0] = su**2 * 2.0 * lu / (np.pi * self.speed) / (1.0 + (lu * omega / self.speed) ** 2)
        return np.stack(out, axis=1)

    def sample(self, n: int, h: float, rng: np.random.Generator) -> np.ndarray:
        """``[n, 5]`` gusts ``u v w`` (m/s) and ``p q`` (rad/s) at step ``h`` (s): each filter discretised exactly
        (ZOH) and driven by white noise of intensity ``pi`` (one-sided PSD 1 per rad/s) held over each step (``q``
        by ``w``'s noise, as the standard derives it), after a warm-up of ten of the slowest time constants."""
        warm = int(np.ceil(10.0 * max(self.scales()) / self.speed / h))
        white = rng.standard_normal((warm + n, 4)) * np.sqrt(np.pi / h)
        out = np.empty((n, 5))
        for j, (num, den) in enumerate(self.filters()):
            num_d, den_d, _ = scipy.signal.cont2discrete((num, den), h, method="zoh")
            out[:, j] = scipy.signal.lfilter(np.ravel(num_d), den_d, white[:, (0, 1, 2, 3, 2)[j]])[warm:]
        return out
