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

import functools
import os
from collections.abc import Callable
from typing import Any

_FLAG = "--xla_cpu_enable_concurrency_optimized_scheduler"

QUICK_COMPILE = {"xla_cpu_use_fusion_emitters": False}
"""``compiler_options`` of the programs that run once or for tens of steps (least-squares solves, Jacobians, one
simulation), where compiling is most of the time: XLA CPU's fusion emitters make faster loops but take about twice
as long to compile. Measured on the output-error polish of flight A (2-core CPU): the solve compiled in 4.5 s with
them and 2.4 s without, and its 30 steps ran in 4.3 s against 4.5 s. The population kernel, run thousands of times,
keeps them (1000 IWO generations: 10.3 s with, 14.0 s without). XLA CPU's own: other backends refuse them, so
programs take them through :func:`quick_jit`."""


def quick_jit(fun: Callable[..., Any], jit: Callable[..., Any] | None = None, **kwargs: Any) -> Callable[..., Any]:
    """``jit(fun, **kwargs)`` (default ``equinox.filter_jit``) compiled with :data:`QUICK_COMPILE` where JAX's default
    backend is the CPU and with XLA's defaults elsewhere: a GPU backend stops at an option it does not know ("No such
    compile option", seen on an H200 with jax 0.11.2)."""
    import equinox as eqx
    import jax

    jit = eqx.filter_jit if jit is None else jit
    quick, plain = jit(fun, compiler_options=QUICK_COMPILE, **kwargs), jit(fun, **kwargs)

    @functools.wraps(fun)
    def call(*args: Any, **kw: Any) -> Any:
        return (quick if jax.default_backend() == "cpu" else plain)(*args, **kw)

    return call


def configure() -> None:
    """Turn the concurrency-optimised CPU scheduler off in ``XLA_FLAGS`` (a user's own setting wins)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if _FLAG not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {_FLAG}=false".strip()
