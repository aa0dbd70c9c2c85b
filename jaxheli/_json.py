"""The package's one JSON helper: nested results as plain Python values, used only at the edges (CLI, files)."""

from __future__ import annotations

from typing import Any

import numpy as np


def json_ready(value: Any) -> Any:
    """Nested dicts/lists/tuples of plain Python values; non-finite floats become ``None``, keys strings."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value if value is None or isinstance(value, str) else str(value)
