"""Stick excitation signals on a time grid: doublet, 3-2-1-1, logarithmic sweep, Schroeder multisine.

Every signal is a pure function of a 1-D time grid ``t`` (s) returning a numpy array ``[N]`` in stick
units; :class:`Excitation` schedules them axis by axis (lat, lon, ped, col) for a piloted flight.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal

import numpy as np
from jaxtyping import ArrayLike, Float

from ..model import INPUT_NAMES

_EDGE_TOL = 1e-9
"""Relative tolerance that puts a sample lying on a pulse edge (up to rounding) after the edge."""


def doublet(
    t: Float[ArrayLike, "N"], start: float, width: float, amplitude: float
) -> Float[np.ndarray, "N"]:
    """``+amplitude`` on ``[start, start + width)``, ``-amplitude`` on the next ``width`` s, zero elsewhere."""
    t = _grid(t, "doublet")
    _require(width > 0, f"doublet: width must be > 0 s, got {width}")
    _require_finite("doublet", start=start, amplitude=amplitude)
    return amplitude * _pulses(t, start, width, np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0]))


def three_two_one_one(
    t: Float[ArrayLike, "N"], start: float, unit: float, amplitude: float
) -> Float[np.ndarray, "N"]:
    """3-2-1-1 input: pulses of 3, 2, 1, 1 ``unit`` s with signs ``+ - + -`` from ``start`` (s).

    The signal spans ``7 unit`` s; its net area is ``amplitude * unit`` (one unit, not zero).
    """
    t = _grid(t, "three_two_one_one")
    _require(unit > 0, f"three_two_one_one: unit must be > 0 s, got {unit}")
    _require_finite("three_two_one_one", start=start, amplitude=amplitude)
    edges = np.array([0.0, 3.0, 5.0, 6.0, 7.0])
    return amplitude * _pulses(t, start, unit, edges, np.array([1.0, -1.0, 1.0, -1.0]))


def sweep(
    t: Float[ArrayLike, "N"],
    f0: float,
    f1: float,
    start: float,
    duration: float,
    amplitude: float,
    *,
    fade: float | None = None,
) -> Float[np.ndarray, "N"]:
    """Logarithmic frequency sweep from ``f0`` to ``f1`` (Hz) over ``[start, start + duration]`` (s).

    Instantaneous frequency ``f0 (f1/f0)^(tau/duration)`` (equal time per octave), phase zero at
    ``start``; raised-cosine fade-in and fade-out of ``fade`` s each (default ``duration / 10``); zero
    outside the sweep.
    """
    t = _grid(t, "sweep")
    _require(f0 > 0 and f1 > 0, f"sweep: frequencies must be > 0 Hz, got f0={f0}, f1={f1}")
    _require(duration > 0, f"sweep: duration must be > 0 s, got {duration}")
    _require_finite("sweep", start=start, amplitude=amplitude, f0=f0, f1=f1)
    fade = duration / 10 if fade is None else fade
    _require(0 <= fade <= duration / 2, f"sweep: fade must lie in [0, duration / 2] s, got {fade}")
    _below_nyquist(t, max(f0, f1), "sweep")
    tau = np.clip(t - start, 0.0, duration)
    ratio = np.log(f1 / f0)
    if ratio == 0.0:
        phase = 2 * np.pi * f0 * tau
    else:
        phase = 2 * np.pi * f0 * duration / ratio * np.expm1(tau * ratio / duration)
    envelope = np.ones_like(t) if fade == 0 else np.minimum(_ramp(tau / fade), _ramp((duration - tau) / fade))
    inside = (t >= start) & (t <= start + duration)
    return np.where(inside, amplitude * envelope * np.sin(phase), 0.0)


def multisine(
    t: Float[ArrayLike, "N"],
    freqs: Float[ArrayLike, "K"],
    amplitude: float,
    *,
    phases: Literal["schroeder", "random"] = "schroeder",
    seed: int = 0,
) -> Float[np.ndarray, "N"]:
    """Sum of equal-amplitude cosines at ``freqs`` (Hz), scaled so that ``max |x| = |amplitude|`` on ``t``.

    ``phases="schroeder"`` uses Schroeder's ``phi_k = -pi k (k - 1) / K`` (frequencies sorted
    ascending) for a low crest factor; ``"random"`` draws uniform phases from ``seed``.
    """
    t = _grid(t, "multisine")
    freqs = np.sort(np.atleast_1d(np.asarray(freqs, dtype=np.float64)))
    _require(freqs.ndim == 1 and freqs.size > 0, f"multisine: freqs must be a non-empty 1-D list, got {freqs}")
    _require(bool(np.all(np.isfinite(freqs)) and np.all(freqs > 0)),
             f"multisine: freqs must be finite and > 0 Hz, got {freqs}")
    _require(bool(np.all(np.diff(freqs) > 0)), f"multisine: freqs must be distinct, got {freqs}")
    _require_finite("multisine", amplitude=amplitude)
    _below_nyquist(t, float(freqs[-1]), "multisine")
    k = np.arange(1, freqs.size + 1)
    if phases == "schroeder":
        phi = -np.pi * k * (k - 1) / freqs.size
    elif phases == "random":
        phi = np.random.default_rng(seed).uniform(0.0, 2 * np.pi, freqs.size)
    else:
        raise ValueError(f"multisine: phases must be 'schroeder' or 'random', got {phases!r}")
    x = np.cos(2 * np.pi * freqs[None, :] * t[:, None] + phi[None, :]).sum(axis=1)
    peak = np.max(np.abs(x))
    _require(peak > 0, "multisine: the signal is identically zero on this grid")
    return amplitude * x / peak


@dataclasses.dataclass(frozen=True)
class Excitation:
    """Stick excitation flown on top of the pilot's feedback, one axis at a time (lat, lon, ped, col).

    After ``lead`` quiet seconds the record is cut into equal slots: ``"3211"`` gives each axis one slot
    starting with a 3-2-1-1 of time ``unit`` (then free response); ``"sweep"`` gives each axis a slot
    filled by a logarithmic sweep over ``band`` (Hz) with ``fade`` s fades; ``"mixed"`` flies all four
    3-2-1-1s, then all four sweeps. ``amplitude`` is the peak stick per axis (normalised stick).
    """

    kind: Literal["3211", "sweep", "mixed"] = "mixed"
    amplitude: tuple[float, float, float, float] = (0.2, 0.2, 0.2, 0.2)
    unit: float = 0.5
    band: tuple[float, float] = (0.2, 4.0)
    fade: float = 1.0
    lead: float = 1.0

    def __post_init__(self) -> None:
        _require(self.kind in ("3211", "sweep", "mixed"),
                 f"Excitation: kind must be '3211', 'sweep' or 'mixed', got {self.kind!r}")
        amp = tuple(float(a) for a in self.amplitude)
        _require(len(amp) == len(INPUT_NAMES) and all(abs(a) <= 1 for a in amp),
                 f"Excitation: amplitude must be 4 sticks in [-1, 1] (lat lon ped col), got {self.amplitude}")
        _require(self.unit > 0, f"Excitation: unit must be > 0 s, got {self.unit}")
        _require(len(self.band) == 2 and 0 < self.band[0] and 0 < self.band[1],
                 f"Excitation: band must be two frequencies > 0 Hz, got {self.band}")
        _require(self.fade >= 0 and self.lead >= 0,
                 f"Excitation: fade and lead must be >= 0 s, got {self.fade}, {self.lead}")
        object.__setattr__(self, "amplitude", amp)
        object.__setattr__(self, "band", (float(self.band[0]), float(self.band[1])))

    def __call__(self, t: Float[ArrayLike, "N"]) -> Float[np.ndarray, "N 4"]:
        """Stick perturbations ``[N, 4]`` (lat lon ped col) on the grid ``t`` (s)."""
        t = _grid(t, "Excitation")
        kinds = {"3211": ["3211"], "sweep": ["sweep"], "mixed": ["3211", "sweep"]}[self.kind]
        n_slots = len(kinds) * len(INPUT_NAMES)
        slot = (t[-1] - t[0] - self.lead) / n_slots
        need = max(7 * self.unit if "3211" in kinds else 0.0, 2 * self.fade if "sweep" in kinds else 0.0)
        _require(slot > need, f"Excitation: a {t[-1] - t[0]:.4g} s record leaves {slot:.4g} s per axis "
                              f"slot, less than the {need:.4g} s one manoeuvre needs; fly longer or shorten "
                              "unit/fade")
        out = np.zeros((t.size, len(INPUT_NAMES)))
        for i, (kind, axis) in enumerate((k, a) for k in kinds for a in range(len(INPUT_NAMES))):
            start = t[0] + self.lead + i * slot
            amp = self.amplitude[axis]
            if kind == "3211":
                out[:, axis] += three_two_one_one(t, start, self.unit, amp)
            else:
                out[:, axis] += sweep(t, *self.band, start, slot, amp, fade=self.fade)
        return out

    def describe(self) -> dict[str, Any]:
        """JSON-friendly description for flight metadata."""
        return {"axes": list(INPUT_NAMES), **dataclasses.asdict(self)}


def _pulses(t: np.ndarray, start: float, unit: float, edges: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """Piecewise-constant ``signs[i]`` between ``start + unit * edges[i]`` and the next edge, zero outside."""
    at = start + unit * edges
    tol = _EDGE_TOL * max(abs(unit), np.max(np.abs(at)))
    segment = np.sum(t[:, None] >= at[None, :] - tol, axis=1)
    return np.concatenate([[0.0], signs, [0.0]])[segment]


def _ramp(x: np.ndarray) -> np.ndarray:
    """Raised-cosine ramp: 0 at ``x <= 0``, 1 at ``x >= 1``."""
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(x, 0.0, 1.0))


def _grid(t: ArrayLike, who: str) -> np.ndarray:
    t = np.asarray(t, dtype=np.float64)
    _require(t.ndim == 1 and t.size > 0, f"{who}: t must be a non-empty 1-D time grid (s), got shape {t.shape}")
    _require(bool(np.all(np.isfinite(t))), f"{who}: t has non-finite samples")
    return t


def _below_nyquist(t: np.ndarray, f_max: float, who: str) -> None:
    if t.size > 1:
        nyquist = 0.5 / np.max(np.diff(t))
        _require(f_max < nyquist,
                 f"{who}: frequency {f_max} Hz is not below the grid's Nyquist frequency {nyquist:.4g} Hz")


def _require_finite(who: str, **values: float) -> None:
    bad = {k: v for k, v in values.items() if not np.isfinite(v)}
    _require(not bad, f"{who}: arguments must be finite, got {bad}")


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise ValueError(message)
