"""Independent optimiser trials spread over several JAX processes (hosts) with ``jax.distributed``.

Every process runs the same script (SPMD): it calls :func:`initialize`, builds the same optimiser and cost
function, and calls :func:`minimize_trials_distributed` with the same ``keys[K]``. Process ``i`` of ``P``
runs a contiguous slice of the keys (sizes differ by at most one, so ``K`` need not divide by ``P``) as
one vmapped :func:`~jaxheli.optim.run.minimize_trials` on its own devices (the cost function may still
shard each population over them, :mod:`jaxheli.sim.shard`); the results are then gathered to every process in
key order, equal to ``minimize_trials(optimizer, cost_fn, keys)`` on a single process. Trials never talk
to each other, so the only communication is that one gather at the end.

Environment read by :func:`initialize` (explicit arguments win):

- ``JAXHELI_COORDINATOR``: ``host:port`` of process 0's coordinator service, reachable from every process.
- ``JAXHELI_NUM_PROCESSES``: how many processes take part (unset or 1: single process, nothing to do).
- ``JAXHELI_PROCESS_ID``: this process's index, ``0 .. JAXHELI_NUM_PROCESSES - 1``.

On CPU the gather goes through gloo collectives over TCP (``jax_cpu_collectives_implementation``).
:func:`launch_local` starts such a group on one machine (tests, :func:`jaxheli.benchmark.trials_scaling.trials_scaling`).
"""

from __future__ import annotations

import os
import socket
import subprocess
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._types import ArrayLike
from .optim._base import AbstractPopulationOptimizer, CostFn, raw_key
from .optim.run import RunResult, minimize_trials

ENV_COORDINATOR = "JAXHELI_COORDINATOR"
ENV_NUM_PROCESSES = "JAXHELI_NUM_PROCESSES"
ENV_PROCESS_ID = "JAXHELI_PROCESS_ID"


def initialize(
    coordinator: str | None = None,
    num_processes: int | None = None,
    process_id: int | None = None,
    *,
    timeout: int = 300,
) -> bool:
    """Join a group of JAX processes; call before any other JAX computation in the process.

    Arguments left ``None`` come from ``JAXHELI_COORDINATOR``, ``JAXHELI_NUM_PROCESSES`` and
    ``JAXHELI_PROCESS_ID`` (module docstring). With one process (or none configured) nothing happens and
    ``False`` is returned; otherwise cross-process CPU collectives are set to gloo,
    ``jax.distributed.initialize`` connects (waiting up to ``timeout`` seconds for the others) and ``True``
    is returned. Calling it again once connected returns ``True`` and does nothing.
    """
    coordinator = coordinator or os.environ.get(ENV_COORDINATOR) or None
    num_processes = _setting(num_processes, ENV_NUM_PROCESSES)
    process_id = _setting(process_id, ENV_PROCESS_ID)
    if num_processes is None or num_processes == 1:
        if coordinator is not None and num_processes is None:
            raise ValueError(f"coordinator {coordinator!r} given but not the number of processes "
                             f"(num_processes or {ENV_NUM_PROCESSES})")
        return False
    if num_processes < 1:
        raise ValueError(f"num_processes ({ENV_NUM_PROCESSES}) must be >= 1, got {num_processes}")
    if coordinator is None:
        raise ValueError(f"{num_processes} processes need a coordinator host:port (coordinator or {ENV_COORDINATOR})")
    if process_id is None or not 0 <= process_id < num_processes:
        raise ValueError(f"process_id ({ENV_PROCESS_ID}) must be in 0..{num_processes - 1}, got {process_id}")
    if jax.distributed.is_initialized():
        return True
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator, num_processes, process_id, initialization_timeout=timeout)
    return True


def _setting(value: int | None, name: str) -> int | None:
    if value is not None:
        return int(value)
    text = os.environ.get(name, "").strip()
    if not text:
        return None
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"environment variable {name} must be an integer, got {text!r}") from None


def trial_slices(trials: int, processes: int) -> list[slice]:
    """Contiguous slices of ``trials`` keys, one per process, sizes differing by at most one (first ones larger)."""
    if trials < 1 or processes < 1:
        raise ValueError(f"need trials >= 1 and processes >= 1, got {trials} and {processes}")
    base, extra = divmod(trials, processes)
    starts = np.cumsum([0] + [base + (i < extra) for i in range(processes)])
    return [slice(int(a), int(b)) for a, b in zip(starts[:-1], starts[1:])]


def minimize_trials_distributed(
    optimizer: AbstractPopulationOptimizer,
    cost_fn: CostFn,
    keys: ArrayLike,
    *,
    checkpoint: str | os.PathLike | None = None,
    **run_options,
) -> RunResult:
    """:func:`~jaxheli.optim.run.minimize_trials` with the trials of ``keys[K]`` split over the processes.

    Call it from every process with the same arguments. Each process runs its slice of the keys
    (:func:`trial_slices`; a process left without one runs ``keys[:1]`` and discards it), then every field of
    the result, the optimiser state included, is gathered to all processes in key order, so the result equals
    a single-process ``minimize_trials(optimizer, cost_fn, keys)``: bitwise when a candidate's cost does not
    depend on the batch it is scored in (float64 costs here do; the float32 blocked kernel rounds differently
    for other batch sizes, and the trials then drift apart as any float32 rerun would). ``run_options`` are those of ``minimize_trials`` (``iterations``, ``chunk``,
    ``progress``, ``resume``); ``checkpoint`` gets the suffix ``.proc<i>`` on process ``i`` (with several
    processes), so a killed run restarted with ``resume=True`` on the same number of processes resumes.
    With a single process this is ``minimize_trials`` itself.
    """
    keys = raw_key(keys)
    if keys.ndim != 2:
        raise ValueError(f"expected keys[K], got key data of shape {keys.shape}")
    count, index = jax.process_count(), jax.process_index()
    if count == 1:
        return minimize_trials(optimizer, cost_fn, keys, checkpoint=checkpoint, **run_options)
    slices = trial_slices(keys.shape[0], count)
    mine = keys[slices[index]] if slices[index].stop > slices[index].start else keys[:1]
    path = None if checkpoint is None else Path(f"{checkpoint}.proc{index}")
    local = minimize_trials(optimizer, cost_fn, mine, checkpoint=path, **run_options)
    return _gather_trials(local, slices)


def _gather_trials(local: RunResult, slices: list[slice]) -> RunResult:
    """Every process's trials (leading axis of each array leaf) to every process, in key order."""
    from jax.experimental.multihost_utils import process_allgather

    width = max(s.stop - s.start for s in slices)
    arrays, static = eqx.partition(local, eqx.is_array)

    def pad(x: jax.Array) -> np.ndarray:
        x = np.asarray(x)
        return np.concatenate([x, np.zeros((width - x.shape[0],) + x.shape[1:], x.dtype)])

    gathered = process_allgather(jax.tree.map(pad, arrays))
    rows = np.concatenate([width * i + np.arange(s.stop - s.start) for i, s in enumerate(slices)])
    arrays = jax.tree.map(lambda x: jnp.asarray(x.reshape((-1,) + x.shape[2:])[rows]), gathered)
    return eqx.combine(arrays, static)


def free_port() -> int:
    """A TCP port on localhost that was free a moment ago (for a local coordinator)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def launch_local(
    argv: Sequence[str],
    num_processes: int,
    *,
    timeout: float = 240.0,
    env: dict[str, str] | None = None,
) -> list[str]:
    """Run ``argv`` as ``num_processes`` local processes joined through a localhost coordinator.

    Each process gets ``JAXHELI_COORDINATOR``, ``JAXHELI_NUM_PROCESSES``, ``JAXHELI_PROCESS_ID`` and
    ``JAX_PLATFORMS=cpu`` on top of ``os.environ`` and ``env`` (which may override them); ``argv`` should call
    :func:`initialize`. Returns each process's stdout. If any process fails, or they are not all done
    after ``timeout`` seconds, the rest are killed and ``RuntimeError`` / ``TimeoutError`` reports the
    exit codes and the tails of their stderr.
    """
    if num_processes < 1:
        raise ValueError(f"num_processes must be >= 1, got {num_processes}")
    shared = {**os.environ, "JAX_PLATFORMS": "cpu", ENV_COORDINATOR: f"127.0.0.1:{free_port()}",
              ENV_NUM_PROCESSES: str(num_processes), **(env or {})}
    with tempfile.TemporaryDirectory(prefix="jaxheli-launch-") as tmp:
        logs = [(Path(tmp) / f"out{i}", Path(tmp) / f"err{i}") for i in range(num_processes)]
        procs = []
        for i, (out, err) in enumerate(logs):
            with open(out, "wb") as fo, open(err, "wb") as fe:
                procs.append(subprocess.Popen(list(argv), stdout=fo, stderr=fe,
                                              env={**shared, ENV_PROCESS_ID: str(i)}))
        failure = _wait_all(procs, time.monotonic() + timeout)
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait()
        if failure is not None:
            tails = "\n".join(f"--- process {i} (exit {p.returncode}) stderr:\n{_tail(err)}"
                              for i, (p, (_, err)) in enumerate(zip(procs, logs)))
            error = TimeoutError if failure == "timeout" else RuntimeError
            raise error(f"{' '.join(argv)} on {num_processes} processes: {failure}\n{tails}")
        return [out.read_text() for out, _ in logs]


def _wait_all(procs: list[subprocess.Popen], deadline: float) -> str | None:
    """``None`` once all exited with 0; a description as soon as one fails or at the deadline."""
    while True:
        codes = [p.poll() for p in procs]
        failed = [i for i, c in enumerate(codes) if c not in (None, 0)]
        if failed:
            return f"process {failed[0]} exited with {codes[failed[0]]}"
        if all(c == 0 for c in codes):
            return None
        if time.monotonic() > deadline:
            return "timeout"
        time.sleep(0.05)


def _tail(path: Path) -> str:
    """The end of a log, without absl's I/W info lines."""
    lines = path.read_text(errors="replace").splitlines()
    return "\n".join(line for line in lines if not line.startswith(("I0000", "W0000")))[-8000:] or "(empty)"
