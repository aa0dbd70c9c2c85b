"""``jaxheli bench``: measure, print and save (JSON, markdown, PNG) the performance of the cost kernels."""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

SCAN_LIMIT = 4.0e7
"""The plain scan materialises ``[P, N, k]`` outputs: larger ``P * N`` are skipped (memory, not speed)."""
QUICK = dict(sizes=[16, 64], samples=[300], dtypes=["float32"], generations=2, experiment_iterations=3, trials=2,
             repeats=1)


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``bench`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser(
        "bench",
        help="measure candidate evaluations/s over P and N, IWO generations, the paper's experiment, devices",
        description="Throughput of the population cost (plain scan and blocked kernel) for every population size P "
        "and flight length N, next to a per-candidate NumPy loop (and mealpy's IWO when installed) measured in "
        "the same run, with the machine's FLOP limit; seconds per IWO generation; the paper's whole experiment "
        "(10 trials x 1000 generations) end to end; and speed-up from sharding the population over local devices.",
    )
    p.add_argument("--sizes", type=int, nargs="+", default=[40, 400, 4000], help="population sizes P")
    p.add_argument("--samples", type=int, nargs="+", default=[1000, 8590, 40000], help="flight lengths N")
    p.add_argument("--dtypes", nargs="+", default=["float32", "float64"], choices=["float32", "float64"])
    p.add_argument("--repeats", type=int, default=3, help="timed repeats per measurement (best counts)")
    p.add_argument("--generations", type=int, default=10, help="IWO generations timed per setting (0: skip)")
    p.add_argument("--experiment-iterations", type=int, default=1000, help="paper experiment generations (0: skip)")
    p.add_argument("--trials", type=int, default=10, help="paper experiment trials")
    p.add_argument("--experiment-data", default=None,
                   help="flight for the paper experiment (default: flight A from the shared data if present, "
                   "else a synthetic 8590-sample flight)")
    p.add_argument("--host-devices", type=int, default=None,
                   help="split the CPU into this many XLA devices (default: the CPU's cores)")
    p.add_argument("--quick", action="store_true", help="tiny settings (a smoke test, seconds)")
    p.add_argument("--out", default="results/bench", help="directory for bench.json, bench.md, throughput.png")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Handler of ``jaxheli bench``."""
    import jax

    devices = args.host_devices or os.cpu_count() or 1
    try:
        jax.config.update("jax_num_cpu_devices", devices)
    except RuntimeError:  # JAX already running in this process (e.g. called from Python): keep its devices
        print(f"jaxheli bench: JAX is already initialised; keeping its {jax.local_device_count()} device(s)")
    jax.config.update("jax_enable_x64", True)
    if args.quick:
        for key, value in QUICK.items():
            setattr(args, key, value)
    result = measure(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from .report import markdown, plot_throughput

    (out / "bench.json").write_text(json.dumps(result, indent=2))
    (out / "bench.md").write_text(markdown(result))
    plot_throughput(result, out / "throughput.png")
    print(markdown(result))
    print(f"wrote {out / 'bench.json'}, {out / 'bench.md'}, {out / 'throughput.png'}")
    return 0


def measure(args: argparse.Namespace) -> dict:
    """Every measurement of one run, as a JSON-ready dict."""
    import jax
    import jax.numpy as jnp

    from ..sim.simulate import make_simulator
    from .baseline import mealpy_rate, numpy_rate
    from .throughput import bench_flight, candidates, evaluation_rate, flops_per_candidate, generation_seconds
    from .throughput import matmul_peak

    devices = jax.local_device_count()
    result: dict = {
        "machine": f"{platform.machine()} {platform.processor() or ''}, {os.cpu_count()} cores, "
        f"jax {jax.__version__}, backend {jax.default_backend()} ({jax.devices()[0].device_kind}), "
        f"{devices} device(s)",
        "devices": devices,
        "settings": {k: v for k, v in vars(args).items() if k != "func"},
        "matmul_peak_flops": {},
        "rates": [],
        "iwo_generation": [],
        "scaling": [],
    }
    flights = {n: bench_flight(n) for n in args.samples}
    baselines = {n: numpy_rate(f, max(2, min(20, 60000 // n))) for n, f in flights.items()}
    for dtype_name in args.dtypes:
        dtype = jnp.dtype(dtype_name)
        peak = matmul_peak(dtype)
        result["matmul_peak_flops"][dtype_name] = peak
        for n, flight in flights.items():
            target = jnp.asarray(flight.outputs, dtype)
            sims = {m: make_simulator(flight, method=m) for m in ("scan", "blocked")}
            for p in args.sizes:
                thetas = candidates(p, dtype)
                row = {"dtype": dtype_name, "N": n, "P": p, "numpy": baselines[n],
                       "flop_limit": peak / flops_per_candidate(n)}
                for method, sim in sims.items():
                    if method == "scan" and p * n > SCAN_LIMIT:
                        continue
                    row[method] = evaluation_rate(sim, thetas, target, args.repeats, shard=False)
                if devices > 1 and p >= 400:
                    sharded = evaluation_rate(sims["blocked"], thetas, target, args.repeats, shard=True)
                    result["scaling"].append({"dtype": dtype_name, "N": n, "P": p, "single": row["blocked"],
                                              "sharded": sharded})
                    row["blocked"] = max(row["blocked"], sharded)
                result["rates"].append(row)
                print(_row_text(row), flush=True)
            if args.generations > 0:
                for method, sim in sims.items():
                    seconds = generation_seconds(sim, target, args.generations)
                    result["iwo_generation"].append({"dtype": dtype_name, "N": n, "method": method, "seconds": seconds})
    mid = min(flights, key=lambda n: abs(n - 8590))
    rate = mealpy_rate(flights[mid])
    result["mealpy"] = None if rate is None else {"N": mid, "rate": rate}
    if args.experiment_iterations > 0:
        result["experiment"] = _experiment(args, baselines)
    return result


def _experiment(args: argparse.Namespace, baselines: dict[int, float]) -> dict:
    import jax
    import jax.numpy as jnp

    from .baseline import numpy_rate
    from .experiment import paper_experiment
    from .throughput import bench_flight

    flight = bench_flight(min(args.samples)) if args.quick else _experiment_flight(args.experiment_data)
    e = paper_experiment(flight, trials=args.trials, iterations=args.experiment_iterations, dtype=jnp.float32,
                         progress=True)
    e["numpy_rate"] = baselines.get(flight.n_samples) or numpy_rate(flight, 4)
    e["devices"] = jax.local_device_count()
    return e


def _experiment_flight(spec: str | None):
    from ..io import load
    from ..io.paths import data_file
    from .throughput import CHANNELS, bench_flight

    if spec:
        return load(spec).select(CHANNELS)
    try:
        return load(data_file("trex550/Data_graphready.mat")).select(CHANNELS)
    except FileNotFoundError:
        return bench_flight(8590)


def _row_text(row: dict) -> str:
    parts = [f"{m} {row[m]:.0f}/s ({row[m] / row['numpy']:.0f}x NumPy)" for m in ("scan", "blocked") if m in row]
    return f"{row['dtype']} N={row['N']} P={row['P']}: " + ", ".join(parts)
