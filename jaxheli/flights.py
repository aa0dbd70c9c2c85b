"""A flight by name: a flight-data file, or :data:`DEFAULT_DATA` for the embedded synthetic flight, optionally a
time window of it (``FILE:t0-t1``, s on the record's own time axis; either end may be left out)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from .data.flight import FlightData
from .data.preprocess import trim
from .io import load
from .synth.piloted import default_flight

DEFAULT_DATA = "default"
"""Name of the embedded synthetic flight (generated on the fly, see :func:`jaxheli.default_flight`)."""

_WINDOW = re.compile(r"^(?P<name>.+):(?P<t0>\d+(?:\.\d*)?)?-(?P<t1>\d+(?:\.\d*)?)?$")


def parse_spec(spec: str | Path) -> tuple[str, float | None, float | None]:
    """``(name, t0, t1)`` of ``FILE`` or ``FILE:t0-t1`` (s; ``None`` for an end left out, or no window).

    A name that is an existing file is taken whole, colon and all."""
    text = str(spec)
    match = _WINDOW.match(text)
    if match is None or Path(text).exists():
        return text, None, None
    t0, t1 = (None if match[k] is None else float(match[k]) for k in ("t0", "t1"))
    if t0 is not None and t1 is not None and t1 <= t0:
        raise ValueError(f"{text}: the window's end {t1} s must come after its start {t0} s")
    return match["name"], t0, t1


def load_flight(spec: str | Path, **options: Any) -> FlightData:
    """The flight ``spec`` names: :func:`jaxheli.default_flight` for :data:`DEFAULT_DATA`, else the file
    :func:`jaxheli.load` reads with ``options`` (``FileNotFoundError`` when there is none); cut to its window
    (:func:`jaxheli.trim`) when ``spec`` is ``NAME:t0-t1``."""
    name, t0, t1 = parse_spec(spec)
    flight = default_flight() if name == DEFAULT_DATA else load(name, **options)
    return flight if t0 is None and t1 is None else trim(flight, t0, t1)
