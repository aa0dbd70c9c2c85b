"""Package layering: the command line stays in ``jaxheli/cli/``, the import graph has no cycle, and importing the
library leaves matplotlib's backend alone.

The graph is read with ``ast`` from the source files (imports at module level and inside functions alike,
relative imports resolved). ``from pkg import name`` is an edge to ``pkg`` (its ``__init__``) unless ``name`` is
a submodule of ``pkg``, in which case the edge goes to that submodule.
"""

import ast
import os
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "jaxheli"
CLI = "jaxheli.cli"
CLI_IMPORTERS = {"jaxheli.__main__"}
"""Modules outside ``jaxheli/cli/`` that may import the command line."""


def _modules() -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its own name, for its ``__init__``)."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """Dotted names ``name`` imports anywhere in its file (within the package: the modules they resolve to)."""
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[: len(base) - node.level + is_package]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module
            for alias in node.names:
                sub = f"{source}.{alias.name}"
                found.add(sub if sub in modules else source)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _in_cli(name: str) -> bool:
    return name == CLI or name.startswith(CLI + ".")


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` (restricted to its own nodes) as a closed path, or ``None``."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node] & graph.keys()):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        state[node] = 2
        stack.pop()
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_argparse_only_in_the_command_line():
    offenders = sorted(n for n, imports in _graph().items() if not _in_cli(n) and "argparse" in imports)
    assert not offenders, f"argparse imported outside jaxheli/cli/: {offenders}"


def test_only_the_command_line_imports_the_command_line():
    offenders = sorted(n for n, imports in _graph().items()
                       if not _in_cli(n) and n not in CLI_IMPORTERS and any(map(_in_cli, imports)))
    assert not offenders, f"modules outside jaxheli/cli/ import jaxheli.cli: {offenders}"


def test_import_graph_has_no_cycle():
    cycle = _cycle(_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_cycle_detection_finds_a_planted_cycle():
    graph = _graph()
    graph["jaxheli.model"] = graph["jaxheli.model"] | {"jaxheli.gap.diagnose"}
    cycle = _cycle(graph)
    assert cycle is not None and cycle[0] == cycle[-1] and "jaxheli.model" in cycle


def test_importing_the_library_keeps_the_matplotlib_backend(tmp_path):
    """In a fresh interpreter on the svg backend: importing every plotting module keeps it, and a plot still
    writes a PNG."""
    png = tmp_path / "convergence.png"
    code = ("import matplotlib; matplotlib.use('svg'); import jaxheli, jaxheli.plots, jaxheli.gap.plots, "
            "jaxheli.report, jaxheli.report.figures, jaxheli.benchmark.report; "
            "assert matplotlib.get_backend() == 'svg', matplotlib.get_backend(); "
            f"jaxheli.plots.plot_convergence({{'a': [3.0, 2.0, 1.0]}}, {str(png)!r}); "
            "assert matplotlib.get_backend() == 'svg', matplotlib.get_backend()")
    path = os.pathsep.join(p for p in (str(PACKAGE.parent), os.environ.get("PYTHONPATH")) if p)
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"} | {"PYTHONPATH": path}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stderr[-2000:]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


BENCHMARK = "jaxheli.benchmark"


def _reach(graph: dict[str, set[str]], start: str) -> set[str]:
    """Every package module ``start`` imports, directly or through others."""
    seen: set[str] = set()
    todo = [start]
    while todo:
        for nxt in graph[todo.pop()] & graph.keys():
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


def test_the_library_never_imports_the_benchmarks():
    """Benchmarks (``jaxheli/benchmark/``) sit above the library: only they and the command line import them."""
    def outside(n: str) -> bool:
        return not (n == BENCHMARK or n.startswith(BENCHMARK + ".") or _in_cli(n) or n in CLI_IMPORTERS)

    offenders = sorted(n for n, imports in _graph().items()
                       if outside(n) and any(i == BENCHMARK or i.startswith(BENCHMARK + ".") for i in imports))
    assert not offenders, f"library modules import jaxheli.benchmark: {offenders}"


def test_the_gap_diagnosis_stands_below_or_beside_identify():
    """No module of ``jaxheli/gap/`` reaches ``jaxheli.identify``, directly or through another module."""
    graph = _graph()
    offenders = sorted(n for n in graph if n.startswith("jaxheli.gap") and "jaxheli.identify" in _reach(graph, n))
    assert not offenders, f"gap modules that reach jaxheli.identify: {offenders}"


def test_reach_follows_imports_through_other_modules():
    graph = {"a": {"b"}, "b": {"c", "numpy"}, "c": set(), "d": {"a"}}
    assert _reach(graph, "a") == {"b", "c"} and _reach(graph, "c") == set()
