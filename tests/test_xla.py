"""The XLA settings of :mod:`jaxheli._xla`: the quick-compile options go to XLA CPU only; the scheduler flag is set by
:func:`jaxheli.configure_xla`, the command line and the test suite, not by importing jaxheli."""

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli import _xla, configure_xla
from jaxheli._xla import FLAG, QUICK_COMPILE, quick_jit, warn_if_unconfigured


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


def test_the_suite_sets_the_scheduler_flag() -> None:
    """tests/conftest.py sets the flag of :func:`jaxheli.configure_xla` before JAX starts (importing jaxheli does not)."""
    assert f"{FLAG}=false" in os.environ["XLA_FLAGS"].split()


def test_configure_xla_after_the_backend_started_warns(monkeypatch: pytest.MonkeyPatch) -> None:
    """Here JAX's backend runs already: the flag still goes into ``XLA_FLAGS`` (for processes started later), with a
    warning; a setting already there is left alone, silently."""
    jnp.zeros(1).block_until_ready()
    monkeypatch.setenv("XLA_FLAGS", "--xla_backend_optimization_level=0")
    with pytest.warns(RuntimeWarning, match="after JAX's backend started"):
        assert configure_xla() is False
    assert os.environ["XLA_FLAGS"] == f"--xla_backend_optimization_level=0 {FLAG}=false"
    monkeypatch.setenv("XLA_FLAGS", f"{FLAG}=true")
    assert configure_xla() is True
    assert os.environ["XLA_FLAGS"] == f"{FLAG}=true"


def test_the_diagnosis_warns_once_without_the_flag(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_xla, "_warned", False)
    warn_if_unconfigured()  # the suite's flag: silent
    monkeypatch.setenv("XLA_FLAGS", "")
    with pytest.warns(RuntimeWarning, match="configure_xla"):
        warn_if_unconfigured()
    warn_if_unconfigured()  # once per process


def test_the_command_line_sets_the_flag(monkeypatch: pytest.MonkeyPatch) -> None:
    """``jaxheli`` sets it first thing (in this process JAX's backend runs already, hence the warning)."""
    from jaxheli.cli import main

    monkeypatch.setenv("XLA_FLAGS", "")
    with pytest.warns(RuntimeWarning), pytest.raises(SystemExit):
        main(["--help"])
    assert os.environ["XLA_FLAGS"] == f"{FLAG}=false"
