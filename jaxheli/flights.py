"""A flight by name: a flight-data file, or :data:`DEFAULT_DATA` for the embedded synthetic flight."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .data.flight import FlightData
from .io import load
from .synth.piloted import default_flight

DEFAULT_DATA = "default"
"""Name of the embedded synthetic flight (generated on the fly, see :func:`jaxheli.default_flight`)."""


def load_flight(spec: str | Path, **options: Any) -> FlightData:
    """The flight ``spec`` names: :func:`jaxheli.default_flight` for :data:`DEFAULT_DATA`, else the file
    :func:`jaxheli.load` reads with ``options`` (``FileNotFoundError`` when there is none)."""
    return default_flight() if spec == DEFAULT_DATA else load(spec, **options)
