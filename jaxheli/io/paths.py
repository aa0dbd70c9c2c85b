"""Where the real TREX 550 flights live: ``$JAXHELI_DATA`` or ``../shared/data`` beside the checkout."""

from __future__ import annotations

import os
from pathlib import Path

ENV_VAR = "JAXHELI_DATA"


def data_dir() -> Path:
    """Directory holding ``trex550/`` and ``px4logs/`` (not shipped; read at run time)."""
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env).expanduser()
    return Path(__file__).resolve().parents[3] / "shared" / "data"


def data_file(relative: str) -> Path:
    """Path of one shared data file, e.g. ``"trex550/ppr_data.mat"``; raises if it is missing."""
    path = data_dir() / relative
    if not path.is_file():
        raise FileNotFoundError(
            f"{path}: shared flight data not found; set ${ENV_VAR} to the folder holding trex550/ and px4logs/"
        )
    return path
