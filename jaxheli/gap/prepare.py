"""A flight made ready for identification or diagnosis: the preparation chain of ``jaxheli prepare`` (and of
``benchmarks/paper_comparison.py``'s training flight), each step optional and logged in the flight's
``metadata["preprocessing"]``."""

from __future__ import annotations

from ..data.flight import FlightData
from ..data.preprocess import lowpass, resample, trim
from .consistency import check, correct
from .thresholds import THRESHOLDS

SAMPLE_S = THRESHOLDS.sample_s
"""The step the diagnosis runs at (s; from the thresholds file): that of the flights its thresholds were set on."""

_CUTOFF = 0.35
"""Low-pass cutoff before a flight is brought to a coarser step, as a fraction of the new sample rate (0.7 of its
Nyquist frequency: the forward-backward order-4 pass keeps about 95 % of the amplitude at half the Nyquist frequency
and 3 % at it)."""


def prepare(
    flight: FlightData, *, window: tuple[float | None, float | None] | None = None, trim_samples: int = 0,
    check_data: bool = False, correct_data: bool = False, lowpass_hz: float | None = None,
    dt: float | None = None,
) -> FlightData:
    """``flight`` cut to ``window`` (``(t0, t1)`` s on its own time axis, ``None`` an open end) and
    ``trim_samples`` dropped at each end, then checked for consistency (:func:`~jaxheli.gap.consistency.check`;
    ``check_data`` records the findings in ``metadata["consistency"]``, ``correct_data`` also applies the
    significant ones), low-passed at ``lowpass_hz`` (zero-phase, inputs too) and resampled to ``dt`` (s), in that
    order."""
    if window is not None or trim_samples:
        start, stop = window if window is not None else (None, None)
        flight = trim(flight, start=start, stop=stop, drop_samples=trim_samples)
    if check_data or correct_data:
        findings = check(flight)
        flight = correct(flight, findings) if correct_data else flight
        flight = flight.replace(metadata={**flight.metadata, "consistency": [f.to_json() for f in findings]})
    if lowpass_hz:
        flight = lowpass(flight, lowpass_hz)
    return resample(flight, dt) if dt else flight


def at_step(flight: FlightData, dt: float | None = SAMPLE_S) -> FlightData:
    """``flight`` at the step ``dt`` (s): unchanged when it is sampled at ``dt`` or slower (or ``dt`` is ``None``),
    else low-passed at ``0.35 / dt`` Hz (zero-phase, inputs too) and resampled to ``dt``."""
    if dt is None or flight.dt >= dt * (1 - 1e-6):
        return flight
    return resample(lowpass(flight, _CUTOFF / dt), dt)
