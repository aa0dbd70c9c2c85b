"""XLA CPU settings jaxheli needs: the scheduler flag, applied on import before any JAX backend starts, and the
compiler options of programs that run only a few times.

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

QUICK_COMPILE = {"xla_cpu_use_fusion_emitters": False}
"""``compiler_options`` of the programs that run once or for tens of steps (least-squares solves, Jacobians, one
simulation), where compiling is most of the time: XLA CPU's fusion emitters make faster loops but take about twice
as long to compile. Measured on the output-error polish of flight A (2-core CPU): the solve compiled in 4.5 s with
them and 2.4 s without, and its 30 steps ran in 4.3 s against 4.5 s. The population kernel, run thousands of times,
keeps them (1000 IWO generations: 10.3 s with, 14.0 s without)."""


def configure() -> None:
    """Turn the concurrency-optimised CPU scheduler off in ``XLA_FLAGS`` (a user's own setting wins)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if _FLAG not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {_FLAG}=false".strip()
