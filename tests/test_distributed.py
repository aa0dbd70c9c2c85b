"""Trials over several JAX processes: two real local processes (CPU, gloo) give what one process gives,
bitwise, uneven splits and a process without trials included; per-process checkpoints resume.

Run as a script (``python tests/test_distributed.py OUT``) this file is one worker of that group.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli import distributed
from jaxheli.optim.iwo import IWO
from jaxheli.optim.run import minimize_trials

LOWER = np.array([-1.0, -2.0, 0.5, -3.0])
UPPER = np.array([1.0, 2.0, 0.5, 3.0])  # axis 2 pinned
IWO_KEYS = 5  # 5 over 2 processes is 3 + 2; a second run of 1 leaves process 1 without a trial


def bowl(thetas):
    """A tilted quadratic with its minimum inside the box, NaN in one corner."""
    cost = jnp.sum((thetas - jnp.array([0.3, -0.7, 0.5, 1.1])[None, :]) ** 2 * jnp.arange(1.0, 5.0)[None, :], axis=1)
    return jnp.where(thetas[:, 0] > 0.9, jnp.nan, cost)


def _iwo():
    """Built on demand: a worker must not touch JAX before it joins the group."""
    return IWO(LOWER, UPPER, iterations=12)


def _keys(seed, count):
    return jax.random.split(jax.random.key(seed), count)


def _leaves(result):
    return [np.asarray(x) for x in jax.tree_util.tree_leaves(result)]


def _worker(out: Path) -> None:
    """One process: a run stopped halfway (as if killed) then resumed from its checkpoint, and a one-trial run."""
    assert distributed.initialize()
    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_numpy_rank_promotion", "raise")
    from jaxheli.optim import run

    index = jax.process_index()
    ckpt = out / "iwo.eqx"
    distributed.minimize_trials_distributed(_iwo(), bowl, _keys(3, IWO_KEYS), iterations=6, chunk=3, progress=False,
                                            checkpoint=ckpt)
    halfway = json.loads(Path(f"{ckpt}.proc{index}.json").read_text())["iteration"]
    chunks, chunk = [], run._chunk
    run._chunk = lambda *a: chunks.append(a[3]) or chunk(*a)
    iwo = distributed.minimize_trials_distributed(_iwo(), bowl, _keys(3, IWO_KEYS), chunk=3, progress=False,
                                                  checkpoint=ckpt, resume=True)
    run._chunk = chunk
    one = distributed.minimize_trials_distributed(_iwo(), bowl, _keys(4, 1), chunk=12, progress=False)
    np.savez(out / f"proc{index}.npz", halfway=halfway, chunks=np.array(chunks), *_leaves(iwo), *_leaves(one))
    jax.distributed.shutdown()


def _single(out: Path) -> None:
    """The reference: one process runs every trial."""
    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_numpy_rank_promotion", "raise")
    reference = _leaves(minimize_trials(_iwo(), bowl, _keys(3, IWO_KEYS), chunk=3, progress=False))
    reference += _leaves(minimize_trials(_iwo(), bowl, _keys(4, 1), chunk=12, progress=False))
    np.savez(out / "single.npz", *reference)


@pytest.mark.slow
def test_two_processes_equal_one(tmp_path):
    """Both sides run in fresh processes under the compiler settings a user runs (the suite's lower LLVM
    optimisation level vectorises a batch of 2 or 3 trials differently from one of 5: 1 ulp, then IWO's
    selection differs)."""
    flags = " ".join(f for f in os.environ.get("XLA_FLAGS", "").split()
                     if not f.startswith("--xla_backend_optimization_level"))
    env = {**os.environ, "XLA_FLAGS": flags, "JAX_PLATFORMS": "cpu"}
    distributed.launch_local([sys.executable, __file__, str(tmp_path)], 2, timeout=240, env={"XLA_FLAGS": flags})
    subprocess.run([sys.executable, __file__, str(tmp_path), "single"], check=True, timeout=240, env=env)
    with np.load(tmp_path / "single.npz") as saved:
        reference = [saved[f"arr_{i}"] for i in range(len(saved.files))]
    assert reference[0].shape == (IWO_KEYS, 4)
    for index, trials in enumerate([3, 2]):
        with np.load(tmp_path / f"proc{index}.npz") as saved:
            assert int(saved["halfway"]) == 6
            assert saved["chunks"].tolist() == [3, 3]  # resumed at generation 6, not started afresh
            got = [saved[f"arr_{i}"] for i in range(len(reference))]
        for mine, ref in zip(got, reference):
            assert mine.dtype == ref.dtype
            np.testing.assert_array_equal(mine, ref)
        header = json.loads((tmp_path / f"iwo.eqx.proc{index}.json").read_text())
        assert header["iteration"] == 12 and len(header["key"]) == trials


def test_single_process_is_minimize_trials(tmp_path):
    keys = _keys(5, IWO_KEYS)  # the shapes of the test above: its compiled chunks are reused
    got = distributed.minimize_trials_distributed(_iwo(), bowl, keys, chunk=3, progress=False,
                                                  checkpoint=tmp_path / "c.eqx")
    for mine, ref in zip(_leaves(got), _leaves(minimize_trials(_iwo(), bowl, keys, chunk=3, progress=False))):
        np.testing.assert_array_equal(mine, ref)
    assert (tmp_path / "c.eqx").exists()
    with pytest.raises(ValueError, match="keys"):
        distributed.minimize_trials_distributed(_iwo(), bowl, jax.random.key(0))


@pytest.mark.parametrize("trials", range(1, 12))
@pytest.mark.parametrize("processes", [1, 2, 3, 4])
def test_trial_slices(trials, processes):
    slices = distributed.trial_slices(trials, processes)
    sizes = [s.stop - s.start for s in slices]
    assert len(slices) == processes and max(sizes) - min(sizes) <= 1 and sizes == sorted(sizes, reverse=True)
    assert np.concatenate([np.arange(trials)[s] for s in slices]).tolist() == list(range(trials))


def test_initialize_settings(monkeypatch):
    for name in (distributed.ENV_COORDINATOR, distributed.ENV_NUM_PROCESSES, distributed.ENV_PROCESS_ID):
        monkeypatch.delenv(name, raising=False)
    assert distributed.initialize() is False
    assert distributed.initialize(num_processes=1) is False
    monkeypatch.setenv(distributed.ENV_NUM_PROCESSES, "1")
    assert distributed.initialize() is False
    monkeypatch.setenv(distributed.ENV_NUM_PROCESSES, "two")
    with pytest.raises(ValueError, match="JAXHELI_NUM_PROCESSES.*'two'"):
        distributed.initialize()
    monkeypatch.setenv(distributed.ENV_NUM_PROCESSES, "2")
    with pytest.raises(ValueError, match="JAXHELI_COORDINATOR"):
        distributed.initialize()
    monkeypatch.setenv(distributed.ENV_COORDINATOR, "127.0.0.1:1")
    with pytest.raises(ValueError, match="JAXHELI_PROCESS_ID"):
        distributed.initialize()
    with pytest.raises(ValueError, match="0..1, got 2"):
        distributed.initialize(process_id=2)
    monkeypatch.delenv(distributed.ENV_NUM_PROCESSES)
    with pytest.raises(ValueError, match="number of processes"):
        distributed.initialize()
    with pytest.raises(ValueError, match=">= 1"):
        distributed.initialize(num_processes=0)


def test_launch_local_reports_failure_and_timeout():
    outs = distributed.launch_local(
        [sys.executable, "-c", "import os; print(os.environ['JAXHELI_PROCESS_ID'], os.environ['JAXHELI_NUM_PROCESSES'])"],
        3, timeout=60)
    assert [o.split() for o in outs] == [["0", "3"], ["1", "3"], ["2", "3"]]
    fail = "import os, sys, time; i = os.environ['JAXHELI_PROCESS_ID']; sys.stderr.write('boom ' + i); " \
           "sys.exit(3) if i == '1' else time.sleep(60)"
    with pytest.raises(RuntimeError, match=r"process 1 exited with 3(.|\n)*boom 1"):
        distributed.launch_local([sys.executable, "-c", fail], 2, timeout=60)
    with pytest.raises(TimeoutError, match="timeout"):
        distributed.launch_local([sys.executable, "-c", "import time; time.sleep(60)"], 2, timeout=1)


def test_cli_wiring(monkeypatch, capsys, tmp_path):
    import argparse

    from jaxheli.benchmark import trials_scaling
    from jaxheli.cli.bench import add_trials_scaling_parser

    seen = {}

    def fake(**kwargs):
        seen.update(kwargs)
        rows = [{"processes": n, "cold_s": 9.0, "warm_s": 4.0 / n, "speedup": float(n), "max_cost_difference": 0.0}
                for n in kwargs["processes"]]
        return {"trials": kwargs["trials"], "iterations": kwargs["iterations"], "samples": kwargs["samples"],
                "dtype": kwargs["dtype"], "cores": 2, "rows": rows}

    monkeypatch.setattr(trials_scaling, "trials_scaling", fake)
    parser = argparse.ArgumentParser()
    add_trials_scaling_parser(parser.add_subparsers())
    args = parser.parse_args(["trials-scaling", "--trials", "3", "--processes", "1", "2", "--out",
                              str(tmp_path / "s.json")])
    assert args.func(args) == 0
    assert seen == {"trials": 3, "iterations": 50, "samples": 1000, "dtype": "float32", "processes": [1, 2],
                    "timeout": 600.0}
    assert "2 process(es): 2.00 s warm" in capsys.readouterr().out
    assert json.loads((tmp_path / "s.json").read_text())["rows"][1]["speedup"] == 2.0


if __name__ == "__main__":
    (_single if sys.argv[2:] == ["single"] else _worker)(Path(sys.argv[1]))
