"""The public namespace: ``jaxheli`` exports exactly the names its docstring lists, each re-exported as
``from ._x import Y as Y``, and importing it changes no environment variable and starts no JAX backend."""

import ast
import json
import os
import re
import subprocess
import sys
import types
from pathlib import Path

import jaxheli

INIT = Path(jaxheli.__file__)


def _documented() -> set[str]:
    """The names of the docstring's bullet list (its last paragraph)."""
    bullets = jaxheli.__doc__.strip().split("\n\n")[-1]
    assert bullets.startswith("- ")
    return set(re.findall(r"``(\w+)``", bullets))


def test_exports_are_exactly_the_documented_names() -> None:
    public = {n for n, v in vars(jaxheli).items() if not n.startswith("_") and not isinstance(v, types.ModuleType)}
    assert public | {"gap", "stages"} == _documented()
    assert isinstance(jaxheli.gap, types.ModuleType) and isinstance(jaxheli.stages, types.ModuleType)


def test_every_name_is_re_exported_as_itself() -> None:
    """``from ._x import Y as Y`` (a type checker's explicit re-export), and only relative imports."""
    for node in ast.parse(INIT.read_text()).body:
        if isinstance(node, ast.Import):
            raise AssertionError(f"line {node.lineno}: plain import in jaxheli/__init__.py")
        if isinstance(node, ast.ImportFrom):
            assert node.level == 1, f"line {node.lineno}: absolute import"
            for alias in node.names:
                assert alias.asname == alias.name, f"line {node.lineno}: {alias.name} not re-exported as itself"


def test_plumbing_stays_in_its_module() -> None:
    from jaxheli._compile_cache import use_compile_cache
    from jaxheli._progress import reporting
    from jaxheli.model import G_SI, R50_SI

    assert callable(use_compile_cache) and callable(reporting) and G_SI > 0 and R50_SI.shape == (40,)
    for name in ("reporting", "use_compile_cache", "G_SI", "R50_SI", "discretize", "resolve_params",
                 "minimize_trials_distributed", "load_ulog", "DEFAULT_PX4"):
        assert not hasattr(jaxheli, name), name


IMPORTS = """
import json, os, sys
import jax  # jax's own import sets TF_CPP_MIN_LOG_LEVEL and TPU_SKIP_MDS_QUERY: not jaxheli's doing
before = dict(os.environ)
import jaxheli, jaxheli.gap, jaxheli.io.mavlink, jaxheli.io.ulog, jaxheli.report, jaxheli.benchmark
library = dict(os.environ)
import jaxheli.cli
from jax._src.xla_bridge import backends_are_initialized
changed = lambda a, b: sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
print(json.dumps({"library": changed(before, library), "cli": changed(library, dict(os.environ)),
                  "backend": backends_are_initialized()}))
"""


def test_importing_changes_no_environment_and_starts_no_backend() -> None:
    """In a fresh process without ``XLA_FLAGS``: importing the library (and the command line, whose ``main`` sets
    its XLA flag before JAX's backend starts) leaves ``os.environ`` as it was and starts no JAX backend."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env["PYTHONPATH"] = os.pathsep.join([str(INIT.parents[1]), env.get("PYTHONPATH", "")])
    run = subprocess.run([sys.executable, "-c", IMPORTS], env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout.splitlines()[-1])
    assert found == {"library": [], "cli": [], "backend": False}
