"""The command line's persistent compilation cache (jaxheli/_compile_cache.py): where it goes, how it is turned
off, and that a run writes its compiled programs there."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from jaxheli._compile_cache import ENV, cache_dir

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("value", ["off", "0", "", "None"])
def test_turned_off(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv(ENV, value)
    assert cache_dir() is None


def test_default_and_named_folder(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv(ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cache_dir() == tmp_path / "jaxheli" / "xla"
    monkeypatch.setenv(ENV, str(tmp_path / "mine"))
    assert cache_dir() == tmp_path / "mine"


def test_command_writes_programs(tmp_path: Path) -> None:
    """As a user runs it: without the suite's cache folder and its quick-compile XLA flags (tests/conftest.py), under
    which every program of this command compiles faster than :data:`~jaxheli._compile_cache.MIN_COMPILE_S`."""
    env = {k: v for k, v in os.environ.items() if k not in ("JAX_COMPILATION_CACHE_DIR", "XLA_FLAGS")}
    env.update({ENV: str(tmp_path / "xla"), "PYTHONPATH": str(ROOT)})
    run = subprocess.run([sys.executable, "-m", "jaxheli", "synth", "--out", str(tmp_path / "f.npz"),
                          "--duration", "40"], env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "f.npz").exists()
    assert any((tmp_path / "xla").glob("*-cache")), "no compiled program written to the cache folder"
