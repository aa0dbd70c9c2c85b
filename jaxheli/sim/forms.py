"""Which form runs a linear recursion in time: the plain scan (one step after another) or the parallel form
(:mod:`jaxheli.sim.parallel`, about ``2 log2 L`` rounds of batched products), chosen by backend and size.

Two recursions have both forms: ``"population"``, the block starts of the population kernel
(:func:`jaxheli.sim.blocked.block_states`, ``steps`` = blocks on the record), and ``"recursion"``, the least-squares
engines' simulations and their tangents (:func:`jaxheli.sim.recursion.linear_recursion`, ``steps`` = samples).
:func:`choose_form` picks one from :data:`PARALLEL_FROM`, the measured table; ``JAXHELI_TIME_FORM`` (``scan`` or
``parallel``) or an explicit ``form`` forces one. The choice is made when a program is traced: set the variable
before the run (a program compiled under one form keeps it).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Literal

TimeForm = Literal["auto", "scan", "parallel"]
Form = Literal["scan", "parallel"]
Recursion = Literal["population", "recursion"]
PATHS: tuple[str, ...] = ("population", "recursion")
FORMS: tuple[str, ...] = ("auto", "scan", "parallel")

ENV = "JAXHELI_TIME_FORM"
"""Environment variable forcing a form (``scan`` or ``parallel``; ``auto`` or unset: :data:`PARALLEL_FROM`)."""
TABLE_ENV = "JAXHELI_TIME_FORM_TABLE"
"""Environment variable naming a ``jaxheli bench`` result (``bench.json``) whose measured selection
(``time_forms.selection``) replaces :data:`PARALLEL_FROM`'s rows for the backends it measured."""

PARALLEL_FROM: dict[str, dict[str, int | None]] = {
    "cpu": {"population": None, "recursion": None},
    "gpu": {"population": 32, "recursion": 64},
}
"""The fewest sequential steps at which the parallel form is used, per backend and path (``None``: never).

CPU: the plain scan was faster in every row measured (``jaxheli bench``'s ``time_forms`` rows on a 2-core CPU:
population cost over N = 1,000 to 40,000 samples and P = 40 to 4,000 candidates in float32, the parallel form 1.5 to
11 times slower; the polish's outputs and Jacobian over the same N, 2.7 to 3.4 times slower; figures in
docs/performance_history.md), so CPU results are the scan's, bit for bit. GPU: provisional, not measured here: a
scan step costs microseconds of loop overhead there whatever its size, which made the one H200 record depth-bound,
so a recursion longer than a few dozen steps is taken to favour the parallel form; replace these rows by the
``selection`` of ``benchmarks/gpu.py``'s ``forms`` step, or point :data:`TABLE_ENV` at that result. Backends not
listed use the scan."""

MAX_PARALLEL_ELEMENTS = 2**30
"""The parallel form materialises one matrix per step (``steps x n x n x batch`` elements, about twice that in the
scan's intermediate rounds); :func:`choose_form` keeps the scan above this many (8 GiB in float64)."""


def backend_key(backend: str) -> str:
    """The table's row for a JAX backend name: ``"gpu"`` for CUDA and ROCm devices, else the name."""
    return "gpu" if backend in ("gpu", "cuda", "rocm") else backend


def measured_table() -> dict[str, dict[str, int | None]]:
    """:data:`PARALLEL_FROM`, with the rows of the bench result named by :data:`TABLE_ENV` (if set) in place."""
    table = {key: dict(row) for key, row in PARALLEL_FROM.items()}
    path = os.environ.get(TABLE_ENV)
    if path:
        selection = json.loads(Path(path).read_text())["time_forms"]["selection"]
        for key, row in selection.items():
            table[backend_key(key)] = {p: row.get(p) for p in PATHS}
    return table


def forced_form() -> TimeForm:
    """The form :data:`ENV` forces (``"auto"`` when unset)."""
    form = os.environ.get(ENV, "auto").strip().lower() or "auto"
    if form not in FORMS:
        raise ValueError(f"{ENV} must be one of {FORMS}, got {form!r}")
    return form  # type: ignore[return-value]


def choose_form(path: Recursion, steps: int, form: TimeForm = "auto", *, elements: int = 0,
                backend: str | None = None) -> Form:
    """``"scan"`` or ``"parallel"`` for a recursion of ``steps`` sequential steps on ``path`` (see the module).

    ``form`` ``"scan"`` / ``"parallel"`` is returned as given; ``"auto"`` defers to :data:`ENV`, then to the measured
    table (:func:`measured_table`) for ``backend`` (default: JAX's default backend), keeping the scan where the
    per-step matrices would hold more than :data:`MAX_PARALLEL_ELEMENTS` ``elements``."""
    if form not in FORMS:
        raise ValueError(f"time form must be one of {FORMS}, got {form!r}")
    if path not in PATHS:
        raise ValueError(f"path must be one of {PATHS}, got {path!r}")
    if form == "auto":
        form = forced_form()
    if form != "auto":
        return form  # type: ignore[return-value]
    if backend is None:
        import jax

        backend = jax.default_backend()
    threshold = measured_table().get(backend_key(backend), {}).get(path)
    if threshold is None or steps < threshold or elements > MAX_PARALLEL_ELEMENTS:
        return "scan"
    return "parallel"
