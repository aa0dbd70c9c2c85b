"""The XLA settings of :mod:`jaxheli._xla`: the quick-compile options go to XLA CPU only."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli._xla import QUICK_COMPILE, quick_jit


def test_quick_jit_gives_the_cpu_options_to_the_cpu_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    """On the CPU the program compiles with :data:`QUICK_COMPILE`; on another backend (a GPU refuses XLA CPU's
    options: "No such compile option") with XLA's defaults."""

    def recording_jit(fun, **kwargs):
        return lambda *args: (kwargs.get("compiler_options"), fun(*args))

    double = quick_jit(lambda x: 2 * x, jit=recording_jit)
    monkeypatch.setattr(jax, "default_backend", lambda: "cpu")
    assert double(3) == (QUICK_COMPILE, 6)
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert double(3) == (None, 6)


def test_quick_jit_compiles_and_keeps_the_function_s_name() -> None:
    def halve(x):
        return x / 2

    fast = quick_jit(halve)
    assert fast.__name__ == "halve"
    np.testing.assert_allclose(fast(jnp.arange(3.0)), [0.0, 0.5, 1.0])
    np.testing.assert_allclose(quick_jit(halve, jit=jax.jit)(jnp.ones(2)), [0.5, 0.5])
