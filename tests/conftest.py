"""Strict test settings: float64, no silent rank promotion; real data required when asked."""

import os
import shutil
import tempfile

# The suite's time goes mostly to compiling many small programs: a lower LLVM optimisation level compiles
# them about 1.4x faster (tests/test_px4log_cli.py: 137 s -> 95 s) and leaves the arithmetic unchanged, and XLA
# CPU's older loop emitters (the library's QUICK_COMPILE for its few-run programs, jaxheli/_xla.py) compile faster
# again (tests/test_identify.py and tests/test_shooting.py: 264 s -> 207 s, one process, measured side by side).
# The diagnosis's joint row fit, run tens of times per diagnosis, keeps level 3 by its own options
# (jaxheli._xla.SOLVE_OFTEN): there the optimised code runs faster than level 0 compiles.
_FLAGS = ["--xla_backend_optimization_level=0", "--xla_cpu_use_fusion_emitters=false"]
# The scheduler setting the diagnosis's batched fits need (jaxheli.configure_xla, which the command line applies and
# importing jaxheli does not), here before JAX is imported; the suite's subprocesses and worker pools inherit it.
_FLAGS.append("--xla_cpu_enable_concurrency_optimized_scheduler=false")
if os.environ.get("PYTEST_XDIST_WORKER"):
    # One busy thread per xdist worker: with `-n 2` on two cores, a worker that also spreads its XLA ops over
    # both cores only slows the other one down (the walkthrough notebook's kernel gets the same setting).
    _FLAGS.append("--xla_cpu_multi_thread_eigen=false")
os.environ["XLA_FLAGS"] = " ".join([os.environ.get("XLA_FLAGS", ""), *_FLAGS]).strip()
_CORES = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_setaffinity") else []
if os.environ.get("PYTEST_XDIST_WORKER") and int(os.environ["PYTEST_XDIST_WORKER_COUNT"]) <= len(_CORES):
    # ...and its own core, before JAX is imported (XLA sizes its spinning thread pools on import to the cores it
    # may use, jaxheli/_affinity.py): the two workers of `-n 2` sharing two cores ran the joint-diagnosis tests
    # 2-5x slower than one pytest on one core. The notebook's kernel and any subprocess inherit the core.
    os.sched_setaffinity(0, {_CORES[int(os.environ["PYTEST_XDIST_WORKER"].removeprefix("gw"))]})

# One on-disk cache of compiled programs for the run's processes (both xdist workers, the notebook's kernel, the
# command-line subprocesses): a program one of them compiled, the others read back instead of compiling it again.
# The run's first pytest process (xdist's controller) names a fresh folder, the processes it starts inherit it, and
# it removes the folder at the end (pytest_unconfigure), so a rerun does the same work as CI's first.
_OWN_CACHE = "JAX_COMPILATION_CACHE_DIR" not in os.environ
if _OWN_CACHE:
    os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="jaxheli-tests-xla-")
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.3")

import gc  # noqa: E402

import jax  # noqa: E402
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")

from jaxheli.io.paths import data_dir  # noqa: E402

REQUIRE_DATA = os.environ.get("JAXHELI_REQUIRE_DATA", "") not in ("", "0")


def pytest_unconfigure(config: pytest.Config) -> None:
    """The process that made the run's compilation cache folder removes it."""
    if _OWN_CACHE:
        shutil.rmtree(os.environ["JAX_COMPILATION_CACHE_DIR"], ignore_errors=True)


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config: pytest.Config) -> None:
    """Under xdist, a crashed worker ends the run naming its test (unless ``--max-worker-restart`` is given):
    replacing it can hang ``--dist loadfile`` forever (pytest-xdist issue 784), which once stalled a run here after
    "node down: Not properly terminated". Set here rather than in ``addopts``, so ``-p no:xdist`` still works."""
    if getattr(config.option, "maxworkerrestart", "") is None:
        config.option.maxworkerrestart = "0"


LONGEST_FIRST = ("test_diagnose.py", "test_notebook.py", "test_blind.py", "test_identify.py", "test_benchmark.py",
                 "test_px4log_cli.py")
"""The files that take longest (by ``--durations``; measured in ``docs/performance_history.md``), collected first.
``--dist loadfile`` hands whole files out in collection order (a first batch to each worker, then one at a time to
whichever is free), so a long file collected late ends the run with the other worker idle."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Collect the :data:`LONGEST_FIRST` files first, in that order; every other file keeps its place."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


MAX_MAPPINGS = 30_000
"""Memory mappings past which a worker drops its compiled programs after a test file (Linux's default limit:
65,530)."""
URGENT_MAPPINGS = 45_000
"""Memory mappings past which a worker drops its compiled programs after any test."""


def _mappings() -> int:
    """Memory mappings of this process (0 where ``/proc`` does not list them)."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return 0


@pytest.fixture(scope="module", autouse=True)
def _release_compiled_programs():
    """Drop every compiled program after a test file once the process holds many memory mappings.

    Each XLA:CPU executable holds a few memory mappings of JIT code; a long-lived xdist worker that compiles
    the whole suite's programs passes Linux's default limit of 65,530 mappings (``vm.max_map_count``; 65,523
    measured near the end of a full run) and the next compile crashes the worker (segfault or abort inside
    ``backend_compile_and_load``). Clearing JAX's caches lets the executables be freed; clearing only past
    :data:`MAX_MAPPINGS` keeps programs that later files share compiled.
    """
    yield
    if _mappings() > MAX_MAPPINGS:
        _release()


@pytest.fixture(autouse=True)
def _release_before_the_limit():
    """Within a test file, drop every compiled program after a test once the process holds
    :data:`URGENT_MAPPINGS` (a file that compiles many programs must not reach the limit before it ends)."""
    yield
    if _mappings() > URGENT_MAPPINGS:
        _release()


def _release() -> None:
    jax.clear_caches()
    gc.collect()


@pytest.fixture(scope="session")
def shared_data():
    """Folder of the real flights; skips when absent unless JAXHELI_REQUIRE_DATA=1 (then fails)."""
    path = data_dir()
    if not (path / "trex550" / "ppr_data.mat").is_file():
        if REQUIRE_DATA:
            pytest.fail(f"JAXHELI_REQUIRE_DATA=1 but the shared flight data is missing at {path}")
        pytest.skip(f"shared flight data not found at {path} (set JAXHELI_DATA)")
    return path
