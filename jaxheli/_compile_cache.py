"""XLA's persistent compilation cache for the command line: a program one run compiled, a later run of the same
shapes reads back from disk instead of compiling it again (a diagnosis compiles about 190 programs).

The folder is ``$JAXHELI_CACHE``, by default ``$XDG_CACHE_HOME/jaxheli/xla`` (``~/.cache/jaxheli/xla``);
``JAXHELI_CACHE=off`` turns it off. JAX's own ``JAX_COMPILATION_CACHE_DIR``, where set, wins. The commands that
time compilation (``bench``, ``trials-scaling``) leave it off unless JAX's variable asks for it.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV = "JAXHELI_CACHE"
"""Environment variable naming the cache folder, or ``off``."""

MIN_COMPILE_S = 0.2
"""Programs that compile faster than this (s) are not written: reading one back costs about as much."""

_OFF = {"", "0", "off", "no", "none", "false"}


def cache_dir() -> Path | None:
    """The folder the command line caches compiled programs in, or ``None`` when ``$JAXHELI_CACHE`` turns it off."""
    value = os.environ.get(ENV)
    if value is not None:
        return None if value.strip().lower() in _OFF else Path(value).expanduser()
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "jaxheli" / "xla"


def use_compile_cache() -> Path | None:
    """Point JAX's persistent compilation cache at :func:`cache_dir` (unless ``JAX_COMPILATION_CACHE_DIR`` is set,
    which JAX reads itself); returns the folder in use, ``None`` when off. Call before the first compilation."""
    if os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return Path(os.environ["JAX_COMPILATION_CACHE_DIR"])
    where = cache_dir()
    if where is None:
        return None
    import jax

    jax.config.update("jax_compilation_cache_dir", str(where))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_S)
    return where
