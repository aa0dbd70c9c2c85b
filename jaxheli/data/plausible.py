"""Plausibility of a loaded flight: every channel within a physical range (units of
:data:`jaxheli.model.STATE_UNITS`, sticks normalised), time stamps in seconds, enough samples to identify
from, and the channels that never move.

Out-of-range values, a sample time outside :data:`DT_RANGE` and records shorter than :data:`MIN_SAMPLES`
are errors unless ``strict=False``, which records them as warnings (``metadata["warnings"]``) for data
the user knows to be legitimate. Constant channels are always a warning only: they are left out of the
default channel set (:func:`jaxheli.data.flight.default_outputs`).
"""

from __future__ import annotations

import numpy as np

from ..model import INPUT_NAMES, STATE_UNITS
from .flight import FlightData, FlightDataError, constant_outputs

LIMITS: dict[str, float] = {
    "u": 100.0, "v": 100.0, "w": 100.0,  # m/s
    "p": 40.0, "q": 40.0, "r": 40.0,  # rad/s: a 2000 deg/s gyro saturates at 35 rad/s
    "phi": 2 * np.pi, "theta": 2 * np.pi,  # rad; unwrapped records may pass pi
    "a": 20.0, "b": 20.0,  # rad; stick multiples in the authors' files (-6.8 x stick)
    **{name: 5.0 for name in INPUT_NAMES},  # normalised sticks: about -1..1, resampling ringing beyond
}
"""Largest plausible magnitude of each channel (units of :data:`STATE_UNITS`; sticks normalised)."""

DT_RANGE = (1e-4, 1.0)
"""Plausible sample times, s (10 kHz .. 1 Hz): beyond, the time column is likely not in seconds."""

MIN_SAMPLES = 10
"""Fewest samples a record may have to be identified from."""


def add_warnings(flight: FlightData, warnings: list[str]) -> FlightData:
    """``flight`` with those of ``warnings`` it does not carry yet appended to ``metadata["warnings"]`` (a flight
    read back from an NPZ keeps its warnings once); itself when nothing is new."""
    known = flight.metadata.get("warnings", [])
    new = [w for w in dict.fromkeys(warnings) if w not in known]
    if not new:
        return flight
    return flight.replace(metadata={**flight.metadata, "warnings": [*known, *new]})


def check_plausible(flight: FlightData, strict: bool = True, where: str | None = None) -> FlightData:
    """``flight`` checked (module docstring): raises on the first implausible finding when ``strict`` (the
    message starts with ``where``, default the flight's source), otherwise returns it with every finding, and
    the constant-channel notice, in ``metadata["warnings"]``."""
    errors = [*_time_problems(flight), *_range_problems(flight)]
    if errors and strict:
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise FlightDataError(f"{where or flight.source}: {errors[0]}{more}; pass strict=False (--no-strict) to "
                              f"load it anyway")
    flat = constant_outputs(flight)
    notes = [f"channel(s) {', '.join(flat)} constant: left out of the default channel set"] if flat else []
    return add_warnings(flight, errors + notes)


def _time_problems(flight: FlightData) -> list[str]:
    out = []
    lo, hi = DT_RANGE
    if not lo <= flight.dt <= hi:
        guess = " (milliseconds?)" if flight.dt > hi else ""
        out.append(f"field 'time': sample time {flight.dt:.6g} s outside {lo:g}..{hi:g} s: time stamps not in "
                   f"seconds{guess}")
    if flight.n_samples < MIN_SAMPLES:
        out.append(f"field 'time': {flight.n_samples} samples; need at least {MIN_SAMPLES} to identify from")
    return out


def _range_problems(flight: FlightData) -> list[str]:
    out = []
    columns = [("inputs", n, flight.inputs[:, i], "normalised") for i, n in enumerate(INPUT_NAMES)]
    columns += [("outputs", n, flight.outputs[:, i], STATE_UNITS.get(n, "")) for i, n in enumerate(flight.output_names)]
    for field, name, values, unit in columns:
        limit = LIMITS[name]
        beyond = np.flatnonzero(np.abs(values) > limit)
        if beyond.size:
            row = int(beyond[0])
            out.append(f"field '{field}' channel '{name}': {beyond.size} sample(s) beyond the plausible "
                       f"+-{limit:g} {unit}, first {values[row]:.6g} at row {row} (t = {flight.time[row]:.6g} s)")
    return out
