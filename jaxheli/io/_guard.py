"""The one door every reader goes through: the path checked, the third-party parsers' console chatter
captured, any exception they raise turned into a :class:`~jaxheli.data.flight.FlightDataError` naming the
file, and the loaded flight's plausibility checked (:func:`jaxheli.data.plausible.check_plausible`)."""

from __future__ import annotations

import contextlib
import functools
import inspect
import io
from pathlib import Path
from typing import Callable

from ..data.flight import FlightData, FlightDataError
from ..data.plausible import add_warnings, check_plausible

_CHATTER_LINES = 3
"""Captured console lines quoted in a warning or an error (the count of the rest is given)."""


def existing_file(path: str | Path) -> Path:
    """``path`` as a ``Path`` when it names a regular file; ``FileNotFoundError`` when nothing is there,
    :class:`FlightDataError` for a directory or anything else that is not a file."""
    path = Path(path)
    if path.is_dir():
        raise FlightDataError(f"{path}: is a directory, not a flight-data file")
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such flight-data file")
    if not path.is_file():
        raise FlightDataError(f"{path}: not a regular file")
    return path


def guarded(fmt: str) -> Callable[[Callable[..., FlightData]], Callable[..., FlightData]]:
    """Decorate the reader of format ``fmt`` (its first argument is the path).

    The decorated reader takes ``strict`` (default True) whether or not the reader itself does: strict,
    implausible data raise; otherwise they become warnings in ``metadata["warnings"]``. A reader that
    declares ``strict`` also receives it."""

    def wrap(read: Callable[..., FlightData]) -> Callable[..., FlightData]:
        passes_strict = "strict" in inspect.signature(read).parameters

        @functools.wraps(read)
        def guarded_read(path: str | Path, *args, strict: bool = True, **kwargs) -> FlightData:
            path = existing_file(path)
            if passes_strict:
                kwargs["strict"] = strict
            chatter = io.StringIO()
            try:
                with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
                    flight = read(path, *args, **kwargs)
            except FlightDataError as exc:
                said = _summary(chatter.getvalue())
                raise FlightDataError(f"{exc}{f' ({said})' if said else ''}") from exc
            except Exception as exc:  # the parsers' own exception types are theirs to choose; none escapes
                said = _summary(chatter.getvalue())
                text = " ".join(str(exc).split())[:300]
                raise FlightDataError(
                    f"{path}: the {fmt} reader failed: {type(exc).__name__}: {text}{f' ({said})' if said else ''}"
                ) from exc
            said = _summary(chatter.getvalue())
            return check_plausible(add_warnings(flight, [said] if said else []), strict=strict, where=str(path))

        return guarded_read

    return wrap


def _summary(text: str) -> str:
    """What a parser printed, in one line: its first lines and the count of the others ('' for nothing)."""
    lines = [" ".join(line.split()) for line in text.splitlines() if line.strip()]
    if not lines:
        return ""
    more = len(lines) - _CHATTER_LINES
    shown = " | ".join(line[:160] for line in lines[:_CHATTER_LINES])
    return f"parser printed {len(lines)} line(s): {shown}" + (f" | ... {more} more" if more > 0 else "")
