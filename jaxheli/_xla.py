"""XLA CPU settings: the scheduler flag the diagnosis's batched fits need (:func:`configure_xla`, which the command
line applies where it starts and a library user calls before JAX's first computation), and the compiler options of
programs that run only a few times (:func:`quick_jit`).

XLA's concurrency-optimised HLO scheduler (on by default on CPU in jaxlib 0.10.2) can deadlock programs that nest
a vmapped ``lax.scan`` with forward-mode tangents inside a loop, such as the batched Levenberg-Marquardt effect fits
of :mod:`jaxheli.gap.fit_effect`: every worker thread waits and the host waits on the result forever. A per-compile
option does not reach it, so the flag goes into ``XLA_FLAGS``, which XLA reads once, when its CPU backend starts.
Importing :mod:`jaxheli` changes no environment variable.
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Callable
from typing import Any

FLAG = "--xla_cpu_enable_concurrency_optimized_scheduler"
"""The XLA flag :func:`configure_xla` sets to ``false``."""

_warned = False

QUICK_COMPILE = {"xla_cpu_use_fusion_emitters": False}
"""``compiler_options`` of the programs that run once or for tens of steps (least-squares solves, Jacobians, one
simulation), where compiling is most of the time: without XLA CPU's fusion emitters a program compiles about twice
as fast and its loops run a little slower. The population kernel, run thousands of times, keeps them. XLA CPU's own:
other backends refuse them, so programs take them through :func:`quick_jit`."""

SOLVE_OFTEN = {**QUICK_COMPILE, "xla_backend_optimization_level": 3}
"""``compiler_options`` of a compiled solve that runs tens of times per process (the diagnosis's row fit: a
forward-mode Jacobian of the predictor at every step): LLVM's optimisations kept even where ``XLA_FLAGS`` lowers
them for compile speed, as the test suite does: unoptimised, its Jacobian runs slower by more than the compile saves.
Level 3 is XLA's default, so elsewhere this changes nothing."""


def quick_jit(fun: Callable[..., Any], jit: Callable[..., Any] | None = None,
              options: dict[str, Any] = QUICK_COMPILE, **kwargs: Any) -> Callable[..., Any]:
    """``jit(fun, **kwargs)`` (default ``equinox.filter_jit``) compiled with ``options`` (:data:`QUICK_COMPILE` or
    :data:`SOLVE_OFTEN`) where JAX's default backend is the CPU and with XLA's defaults elsewhere: a GPU backend stops
    at an option it does not know ("No such compile option")."""
    import equinox as eqx
    import jax

    jit = eqx.filter_jit if jit is None else jit
    quick, plain = jit(fun, compiler_options=options, **kwargs), jit(fun, **kwargs)

    @functools.wraps(fun)
    def call(*args: Any, **kw: Any) -> Any:
        return (quick if jax.default_backend() == "cpu" else plain)(*args, **kw)

    return call


def configure_xla() -> bool:
    """Turn XLA CPU's concurrency-optimised scheduler off (``--xla_cpu_enable_concurrency_optimized_scheduler=false``
    appended to ``os.environ["XLA_FLAGS"]``), which the diagnosis's batched effect fits (:mod:`jaxheli.gap`) need on
    the CPU; a setting of the flag already in ``XLA_FLAGS`` wins. Processes started afterwards inherit it.

    Call it once, before JAX's first computation: XLA reads ``XLA_FLAGS`` when its backend starts. The command line
    calls it itself. Returns ``True`` when the flag is in ``XLA_FLAGS`` in time; ``False``, with a warning, when JAX's
    backend had started already (then only processes started afterwards get it)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if FLAG in flags:
        return True
    os.environ["XLA_FLAGS"] = f"{flags} {FLAG}=false".strip()
    if _backend_started():
        warnings.warn("jaxheli.configure_xla() was called after JAX's backend started: XLA_FLAGS is read when the "
                      "backend starts, so the scheduler setting reaches only processes started from now on; call "
                      "it before the first JAX computation", RuntimeWarning, stacklevel=2)
        return False
    return True


def warn_if_unconfigured() -> None:
    """Warn once per process when JAX computes on the CPU and ``XLA_FLAGS`` does not set the scheduler flag of
    :func:`configure_xla` (the diagnosis's batched fits may then hang)."""
    global _warned
    if _warned or FLAG in os.environ.get("XLA_FLAGS", ""):
        return
    import jax

    if jax.default_backend() != "cpu":
        return
    _warned = True
    warnings.warn(f"XLA CPU's concurrency-optimised scheduler is on ({FLAG}=false is not in XLA_FLAGS): the "
                  "diagnosis's batched fits can hang with it; call jaxheli.configure_xla() before the first JAX "
                  "computation (the jaxheli command does)", RuntimeWarning, stacklevel=3)


def _backend_started() -> bool:
    """Whether JAX has started a backend in this process (``False`` where JAX cannot say)."""
    try:
        from jax._src.xla_bridge import backends_are_initialized
    except ImportError:
        return False
    return bool(backends_are_initialized())
