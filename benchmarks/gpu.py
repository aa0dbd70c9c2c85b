#!/usr/bin/env python3
"""One command for a GPU machine: install jaxheli with a CUDA build of JAX, then measure, each step under its own
timeout inside one budget (default 290 s), writing JSON under ``$OUT`` (or ``--out``).

    python3 benchmarks/gpu.py                                     # on the GPU machine, from the repository root
    python3 benchmarks/gpu.py --tiny --no-install --out /tmp/gt   # the same steps at tiny sizes (a check on a CPU)

Steps, in order of priority (a step starts only while the budget has at least ``--min-step`` seconds left):

1. ``install``: ``pip install -e .`` and ``jax[cuda13]==0.10.2`` or ``jax[cuda12]==0.10.2`` (``nvidia-smi``'s CUDA
   version picks; the other is tried if the first fails). A JAX that already sees the GPU is kept as it is (its
   version recorded) and jaxheli's other dependencies installed beside it. Outside a virtual environment the script
   first makes ``.venv-gpu`` (``--system-site-packages``, so a JAX of the machine's image stays visible) and runs
   itself there.
2. ``forms``: ``jaxheli bench``'s scan-against-parallel rows, population cost over N = 1000, 8590, 40000 and
   P = 40, 400, 4000 (float32) and the polish's outputs and Jacobian over N, with the table they select
   (``bench.json``'s ``time_forms.selection``; point ``JAXHELI_TIME_FORM_TABLE`` at it, or copy it into
   ``jaxheli/sim/forms.py``'s ``PARALLEL_FROM``).
3. ``experiment``: the paper's experiment (10 trials, 200 IWO generations, N = 8590) under the parallel form and
   under the scan.
4. ``main-job``: README's main job, ``jaxheli identify --data default --iterations 100`` (the forms ``auto`` picks).
5. ``time-to-model``: IWO (100 generations) + polish from a fresh process, parallel form and scan.
6. ``throughput``: the throughput rows of ``jaxheli bench`` (plain scan against the blocked kernel) over the same P
   and N, seconds per IWO generation.
7. ``main-job-scan``: the main job again with ``JAXHELI_TIME_FORM=scan``, for the speed-up of the parallel form.

``gpu.json`` in the output folder (rewritten after every step) holds each step's command, status, seconds and
output folder, the environment (devices, versions), and the headline figures: the selected table, the experiment's
seconds per form, the main job's wall time. Assumptions: the GPU machine reaches a package index holding
``jax-cuda12-plugin`` / ``jax-cuda13-plugin`` 0.10.2 and their NVIDIA wheels (checked on the development machine's
index: both exist, the ``cuda12`` / ``cuda13`` extras of jax 0.10.2 pin them), or its image already has a JAX that
sees the GPU plus pip access to jaxheli's pure-Python dependencies; otherwise the install fails, is recorded, and
the measurements run on whatever JAX there is (``gpu.json`` names the backend). ``XLA_PYTHON_CLIENT_PREALLOCATE`` is
set to ``false`` so that the fresh processes of the time to a model find GPU memory free. The budget counts the
install too: a slow index leaves less time for the later steps.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
JAX_VERSION = "0.10.2"
VENV = ROOT / ".venv-gpu"

FULL = {
    "forms": ["--samples", "8590", "--form-samples", "1000", "8590", "40000", "--form-sizes", "40", "400", "4000",
              "--repeats", "3"],
    "experiment": ["--samples", "8590", "--experiment-iterations", "200", "--trials", "10"],
    "main-job": ["--data", "default", "--iterations", "100"],
    "time-to-model": ["--samples", "8590", "--model-methods", "iwo+polish", "--model-iterations", "100"],
    "throughput": ["--sizes", "40", "400", "4000", "--samples", "1000", "8590", "40000", "--generations", "3",
                   "--repeats", "3"],
    "main-job-scan": ["--data", "default", "--iterations", "100"],
}
TINY = {
    "forms": ["--samples", "300", "--form-samples", "300", "--form-sizes", "16", "--repeats", "1"],
    "experiment": ["--samples", "300", "--experiment-iterations", "3", "--trials", "2", "--data", "default:0-3"],
    "main-job": ["--data", "default:0-5", "--iterations", "3", "--polish-steps", "2", "--polish-rounds", "1",
                 "--freq-starts", "1", "--freq-steps", "2"],
    "time-to-model": ["--samples", "300", "--model-methods", "iwo+polish", "--model-iterations", "3",
                      "--data", "default:0-3"],
    "throughput": ["--sizes", "16", "--samples", "300", "--generations", "1", "--repeats", "1"],
    "main-job-scan": ["--data", "default:0-5", "--iterations", "3", "--polish-steps", "2", "--polish-rounds", "1",
                      "--freq-starts", "1", "--freq-steps", "2"],
}
CAPS = {"install": 150, "forms": 100, "experiment": 110, "main-job": 90, "time-to-model": 100, "throughput": 80,
        "main-job-scan": 90}
"""Each step's own timeout (s); the budget left cuts it shorter."""

# every bench step but `throughput` skips what the others measure
QUIET_BENCH = ["--sizes", "--generations", "0", "--experiment-iterations", "0", "--model-methods", "--no-costs",
               "--form-samples", "--dtypes", "float32", "--host-devices", "1", "--quiet"]


class Budget:
    """Seconds left of the run's budget."""

    def __init__(self, seconds: float):
        self.end = time.monotonic() + seconds

    def left(self) -> float:
        return self.end - time.monotonic()


def run(cmd: list[str], timeout: float, log: Path, env: dict[str, str] | None = None) -> dict:
    """Run ``cmd`` (its own process group, output to ``log``) for at most ``timeout`` s; its status and seconds."""
    t0 = time.perf_counter()
    with open(log, "ab") as out:
        out.write(f"$ {' '.join(cmd)}\n".encode())
        out.flush()
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT, env=env,
                                start_new_session=True)
        try:
            rc = proc.wait(timeout=max(timeout, 1.0))
            status = "ok" if rc == 0 else "failed"
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)  # the step and the processes it started (its own group)
            proc.wait()
            rc, status = None, "timeout"
    return {"command": " ".join(cmd), "rc": rc, "status": status, "seconds": round(time.perf_counter() - t0, 2),
            "log": str(log)}


def probe(python: str) -> dict:
    """JAX's version, backend and devices as ``python`` sees them (``None`` when JAX does not import)."""
    code = ("import json, jax; d = jax.devices(); print(json.dumps({'jax': jax.__version__, 'backend': "
            "jax.default_backend(), 'devices': [str(x) for x in d], 'kind': d[0].device_kind}))")
    try:
        done = subprocess.run([python, "-c", code], capture_output=True, text=True, timeout=120)
        if done.returncode != 0:
            return {"error": done.stderr[-800:]}
        return json.loads(done.stdout.strip().splitlines()[-1])
    except (subprocess.TimeoutExpired, IndexError, json.JSONDecodeError) as error:
        return {"error": repr(error)}


def cuda_major() -> int | None:
    """The CUDA version ``nvidia-smi`` reports the driver supports (its major number), or ``None``."""
    if shutil.which("nvidia-smi") is None:
        return None
    try:
        text = subprocess.run(["nvidia-smi"], capture_output=True, text=True, timeout=60).stdout
    except subprocess.TimeoutExpired:
        return None
    found = re.search(r"CUDA Version:\s*(\d+)", text)
    return int(found.group(1)) if found else None


def install(python: str, budget: Budget, out: Path) -> dict:
    """The install step (see the module): what ran, and JAX as the environment then sees it."""
    log, steps = out / "install.log", []
    pip = [python, "-m", "pip", "install", "--disable-pip-version-check"]
    before = probe(python)

    def step(cmd: list[str]) -> bool:
        steps.append(run(cmd, min(CAPS["install"], budget.left() - 30), log))
        return steps[-1]["status"] == "ok"

    if before.get("backend") == "gpu":  # keep the image's JAX: jaxheli and its other dependencies beside it
        pins = out / "keep-jax.txt"
        jaxlib = subprocess.run([python, "-c", "import jaxlib; print(jaxlib.__version__)"], capture_output=True,
                                text=True).stdout.strip()
        pins.write_text(f"jax=={before['jax']}\n" + (f"jaxlib=={jaxlib}\n" if jaxlib else ""))
        deps = [d for d in tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
                if not re.match(r"jax(lib)?\b", d)]
        step(pip + ["--no-deps", "-e", "."]) and step(pip + ["-c", str(pins)] + deps)
        how = f"kept the machine's JAX {before['jax']}"
    else:
        major = cuda_major()
        order = [13, 12] if (major or 13) >= 13 else [12, 13]
        how = "pip install -e . failed"
        if step(pip + ["-e", "."]):
            how = "no CUDA JAX installed (no nvidia-smi)" if major is None else "the CUDA JAX install failed"
            for cuda in order if major is not None else []:
                if step(pip + [f"jax[cuda{cuda}]=={JAX_VERSION}"]):
                    how = f"jax[cuda{cuda}]=={JAX_VERSION} (driver CUDA {major})"
                    break
    return {"before": before, "after": probe(python), "how": how, "steps": steps}


def bench(python: str, name: str, sizes: dict[str, list[str]], out: Path, extra: list[str]) -> list[str]:
    """The ``jaxheli bench`` command of step ``name`` writing into ``out / name``."""
    return [python, "-m", "jaxheli", "bench", *QUIET_BENCH, *sizes[name], *extra, "--out", str(out / name)]


def headline(out: Path, summary: dict) -> dict:
    """The figures worth reading first, from the steps' own JSON files."""
    found: dict = {}
    forms = out / "forms" / "bench.json"
    if forms.is_file():
        found["selection"] = json.loads(forms.read_text())["time_forms"]["selection"]
    experiment = out / "experiment" / "bench.json"
    if experiment.is_file():
        found["experiment_s"] = {e["time_form"]: round(e["seconds"], 2)
                                 for e in json.loads(experiment.read_text()).get("experiments", [])}
    model = out / "time-to-model" / "bench.json"
    if model.is_file():
        found["time_to_model_s"] = {f"{r['method']} {r['time_form']}": round(r["seconds"], 2)
                                    for r in json.loads(model.read_text()).get("time_to_model", [])}
    for name in ("main-job", "main-job-scan"):
        main = next((s for s in summary["steps"] if s["name"] == name and "seconds" in s), None)
        if main:
            found[f"{name.replace('-', '_')}_s"] = main["seconds"] if main["status"] == "ok" else main["status"]
    return found


def _commit() -> str | None:
    """The checkout's commit (with ``+dirty`` when files differ from it), or ``None`` without git."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=30)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.TimeoutExpired):
        return None
    return head.stdout.strip() + ("+dirty" if dirty else "") if head.returncode == 0 else None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=os.environ.get("OUT") or f"results/gpu-{time.strftime('%Y%m%d-%H%M%S')}",
                        help="output folder (default: $OUT, else results/gpu-DATE)")
    parser.add_argument("--budget", type=float, default=290.0, help="seconds for the whole run, install included")
    parser.add_argument("--min-step", type=float, default=25.0, help="fewest seconds left for a step to start")
    parser.add_argument("--no-install", action="store_true", help="use the JAX and jaxheli already installed")
    parser.add_argument("--tiny", action="store_true", help="tiny sizes (a check of the steps, on a CPU too)")
    parser.add_argument("--steps", nargs="+", default=list(FULL), choices=list(FULL), help="steps to run, in order")
    parser.add_argument("--step-timeout", type=float, default=None,
                        help="every step's own timeout, s (default: each step's in CAPS; a slow CPU check needs more)")
    args = parser.parse_args(argv)
    budget = Budget(args.budget)
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)

    python = sys.executable
    if not args.no_install and sys.prefix == sys.base_prefix:  # not in a virtual environment: make one
        made = (VENV / "bin" / "python").exists() or subprocess.run(
            [python, "-m", "venv", "--system-site-packages", str(VENV)]).returncode == 0
        if made:
            env = {**os.environ, "OUT": str(out)}
            rest = list(argv if argv is not None else sys.argv[1:])
            os.execve(str(VENV / "bin" / "python"), [str(VENV / "bin" / "python"), __file__, *rest], env)
        print("gpu.py: could not make a virtual environment; installing into this Python", flush=True)

    summary: dict = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "budget_s": args.budget, "tiny": args.tiny,
                     "machine": f"{platform.node()} {platform.machine()}, {os.cpu_count()} cores",
                     "python": python, "commit": _commit(), "steps": []}
    gpu_json = out / "gpu.json"

    def save() -> None:
        summary["headline"] = headline(out, summary)
        gpu_json.write_text(json.dumps(summary, indent=2))

    if args.no_install:
        summary["install"] = {"how": "skipped (--no-install)", "after": probe(python)}
    else:
        summary["install"] = install(python, budget, out)
    summary["environment"] = summary["install"]["after"]
    if shutil.which("nvidia-smi"):
        summary["nvidia_smi"] = subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True).stdout.strip()
    save()

    env = {**os.environ, "XLA_PYTHON_CLIENT_PREALLOCATE": "false", "PYTHONPATH": str(ROOT)}
    env.pop("JAXHELI_TIME_FORM", None)  # each step's forms are its own (auto unless it says)
    sizes = TINY if args.tiny else FULL
    commands = {
        "forms": bench(python, "forms", sizes, out, []),
        "experiment": bench(python, "experiment", sizes, out, ["--forms", "parallel", "scan"]),
        "main-job": [python, "-m", "jaxheli", "identify", *sizes["main-job"], "--quiet", "--out",
                     str(out / "main-job")],
        "main-job-scan": [python, "-m", "jaxheli", "identify", *sizes["main-job-scan"], "--quiet", "--out",
                          str(out / "main-job-scan")],
        "time-to-model": bench(python, "time-to-model", sizes, out, ["--forms", "parallel", "scan"]),
        "throughput": [python, "-m", "jaxheli", "bench", "--dtypes", "float32", "--experiment-iterations", "0",
                       "--model-methods", "--no-costs", "--form-samples", "--host-devices", "1", "--quiet",
                       *sizes["throughput"], "--out", str(out / "throughput")],
    }
    caps = {name: args.step_timeout or cap for name, cap in CAPS.items()}
    for name in args.steps:
        left = budget.left()
        if left < args.min_step:
            summary["steps"].append({"name": name, "status": "skipped", "reason": f"{left:.0f} s of budget left"})
            save()
            continue
        print(f"gpu.py: {name} (at most {min(caps[name], left - 5):.0f} s)", flush=True)
        step_env = {**env, "JAXHELI_TIME_FORM": "scan"} if name == "main-job-scan" else env
        summary["steps"].append({"name": name, **run(commands[name], min(caps[name], left - 5), out / f"{name}.log",
                                                      step_env)})
        print(f"gpu.py: {name} {summary['steps'][-1]['status']} in {summary['steps'][-1]['seconds']} s", flush=True)
        save()
    print(json.dumps(summary["headline"], indent=2))
    print(f"gpu.py: wrote {gpu_json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
