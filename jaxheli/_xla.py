"""XLA CPU settings jaxheli needs, applied on import before any JAX backend starts.

XLA's concurrency-optimised HLO scheduler (on by default on CPU in jaxlib 0.10.2) deadlocks some programs
that nest a vmapped ``lax.scan`` with forward-mode tangents inside a loop, such as the batched
Levenberg-Marquardt effect fits of :mod:`jaxheli.gap.fit_effect`: every worker thread waits and the host
waits on the result forever (seen with 8 candidates of up to 16 parameters on a 240-sample flight). A
per-compile option does not reach it, so the flag goes into ``XLA_FLAGS``, unless the user set it; it
takes effect only when ``jaxheli`` is imported before JAX's CPU backend is first used.
"""

from __future__ import annotations

import os

_FLAG = "--xla_cpu_enable_concurrency_optimized_scheduler"


def configure() -> None:
    """Turn the concurrency-optimised CPU scheduler off in ``XLA_FLAGS`` (a user's own setting wins)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if _FLAG not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {_FLAG}=false".strip()
