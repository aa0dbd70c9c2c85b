"""``FlightData``: one flight record (time, stick inputs, measured outputs) with names, units and source."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..model import FLAPPING, INPUT_NAMES, MEASURABLE, STATE_UNITS


class FlightDataError(ValueError):
    """Bad flight data: the message names the source file, the field and the problem."""


@dataclasses.dataclass(frozen=True, eq=False)
class FlightData:
    """A uniformly sampled flight record.

    Attributes:
        time: ``[N]`` sample times, s, strictly increasing and uniform (spacing ``dt``).
        inputs: ``[N, 4]`` normalised sticks ``lat lon ped col``.
        outputs: ``[N, k]`` measured outputs, columns named by ``output_names`` (states of the model,
            units of :data:`jaxheli.model.STATE_UNITS`: m/s, rad/s, rad).
        output_names: names of the ``k`` output columns, a subset of :data:`jaxheli.model.MEASURABLE`.
        source: where the data came from (file path or generator description).
        metadata: free-form provenance (reader, message mapping, preprocessing steps, truth parameters).
    """

    time: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    output_names: tuple[str, ...]
    source: str = "<memory>"
    metadata: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        src = self.source
        for field in ("time", "inputs", "outputs"):
            if np.iscomplexobj(getattr(self, field)):
                raise FlightDataError(f"{src}: field '{field}': complex values; flight data must be real")
        time = np.asarray(self.time, dtype=np.float64)
        inputs = np.asarray(self.inputs, dtype=np.float64)
        outputs = np.asarray(self.outputs, dtype=np.float64)
        names = tuple(self.output_names)
        if time.ndim != 1 or time.size < 2:
            raise FlightDataError(f"{src}: field 'time': expected a 1-D array of >= 2 samples, got shape {time.shape}")
        n = time.size
        if inputs.shape != (n, len(INPUT_NAMES)):
            raise FlightDataError(f"{src}: field 'inputs': expected shape ({n}, 4) [lat lon ped col], got {inputs.shape}")
        if outputs.ndim != 2 or outputs.shape[0] != n:
            raise FlightDataError(f"{src}: field 'outputs': expected shape ({n}, k), got {outputs.shape}")
        if outputs.shape[1] != len(names):
            raise FlightDataError(
                f"{src}: field 'output_names': {len(names)} names for {outputs.shape[1]} output columns"
            )
        bad = [c for c in names if c not in MEASURABLE]
        if bad or len(set(names)) != len(names):
            raise FlightDataError(
                f"{src}: field 'output_names': {names} must be distinct names from {MEASURABLE}"
            )
        for field, arr, labels in (("time", time[:, None], ("time",)), ("inputs", inputs, INPUT_NAMES),
                                   ("outputs", outputs, names)):
            finite = np.isfinite(arr)
            if not finite.all():
                row, col = np.argwhere(~finite)[0]
                raise FlightDataError(
                    f"{src}: field '{field}' channel '{labels[col]}': {int((~finite).sum())} non-finite "
                    f"samples (NaN/Inf), first at row {row} (t = {time[row] if field != 'time' else 'n/a'})"
                )
        steps = np.diff(time)
        if (steps <= 0).any():
            row = int(np.argmax(steps <= 0))
            raise FlightDataError(
                f"{src}: field 'time': not strictly increasing at row {row + 1} "
                f"({time[row]:.6g} -> {time[row + 1]:.6g} s)"
            )
        dt = float(np.median(steps))
        if np.max(np.abs(steps - dt)) > 1e-3 * dt + 1e-9:
            row = int(np.argmax(np.abs(steps - dt)))
            raise FlightDataError(
                f"{src}: field 'time': uneven sampling (median step {dt:.6g} s, step {steps[row]:.6g} s at "
                f"row {row + 1}); resample first (jaxheli.resample)"
            )
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "inputs", inputs)
        object.__setattr__(self, "outputs", outputs)
        object.__setattr__(self, "output_names", names)
        object.__setattr__(self, "metadata", dict(self.metadata))

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return float((self.time[-1] - self.time[0]) / (self.time.size - 1))

    @property
    def n_samples(self) -> int:
        """Number of samples ``N``."""
        return int(self.time.size)

    @property
    def duration(self) -> float:
        """Record length, s."""
        return float(self.time[-1] - self.time[0])

    @property
    def input_names(self) -> tuple[str, ...]:
        """Names of the four input columns."""
        return INPUT_NAMES

    @property
    def units(self) -> dict[str, str]:
        """Units of every column: time s, sticks normalised, outputs per :data:`STATE_UNITS`."""
        out = {"time": "s"}
        out.update({n: "normalised stick" for n in INPUT_NAMES})
        out.update({n: STATE_UNITS[n] for n in self.output_names})
        return out

    def output(self, name: str) -> np.ndarray:
        """One output column ``[N]`` by name."""
        if name not in self.output_names:
            raise KeyError(f"{self.source}: no output channel '{name}' (has {self.output_names})")
        return self.outputs[:, self.output_names.index(name)]

    def select(self, names: tuple[str, ...] | list[str]) -> FlightData:
        """A copy holding only the named output channels, in that order."""
        missing = [n for n in names if n not in self.output_names]
        if missing:
            raise FlightDataError(
                f"{self.source}: field 'outputs': channel(s) {missing} not in the flight (has {self.output_names})"
            )
        cols = [self.output_names.index(n) for n in names]
        return self.replace(outputs=self.outputs[:, cols], output_names=tuple(names))

    def replace(self, **changes: Any) -> FlightData:
        """A copy with some fields replaced (validated again)."""
        return dataclasses.replace(self, **changes)

    def __repr__(self) -> str:
        return (
            f"FlightData(source={self.source!r}, N={self.n_samples}, dt={self.dt:.6g} s, "
            f"duration={self.duration:.4g} s, outputs={self.output_names})"
        )


def constant_outputs(flight: FlightData) -> tuple[str, ...]:
    """Output channels whose samples never change (no correlation can be computed on them)."""
    return tuple(c for c, spread in zip(flight.output_names, np.ptp(flight.outputs, axis=0)) if spread == 0)


def default_outputs(flight: FlightData) -> tuple[str, ...]:
    """The flight's measured channels without the flapping columns (:data:`jaxheli.model.FLAPPING`) and
    without the constant ones (:func:`constant_outputs`)."""
    flat = constant_outputs(flight)
    return tuple(c for c in flight.output_names if c not in FLAPPING and c not in flat)
