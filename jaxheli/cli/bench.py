"""``jaxheli bench | trials-scaling``: performance of the cost kernels, and of trials spread over processes."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from ._options import OldForm, add_data_option, add_quiet_option, adopt_as_data, fit_step


def add_bench_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``bench`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser(
        "bench",
        help="measure candidate evaluations/s over P and N, IWO generations, the paper's experiment, devices",
        description="Throughput of the population cost (plain scan and blocked kernel) for every population size P "
        "and flight length N, next to a per-candidate NumPy loop (and mealpy's IWO when installed) measured in "
        "the same run, with the machine's FLOP limit; seconds per IWO generation; the paper's whole experiment "
        "(10 trials x 1000 generations) end to end; speed-up from sharding the population over local devices; and "
        "the plain scan against the parallel-in-time form of each recursion, with the table of forms they select.",
    )
    p.add_argument("--sizes", type=int, nargs="*", default=[40, 400, 4000], help="population sizes P (none: skip "
                   "the throughput rows)")
    p.add_argument("--samples", type=int, nargs="+", default=[1000, 8590, 40000], help="flight lengths N")
    p.add_argument("--dtypes", nargs="+", default=["float32", "float64"], choices=["float32", "float64"])
    p.add_argument("--repeats", type=int, default=3, help="timed repeats per measurement (best counts)")
    p.add_argument("--generations", type=int, default=10, help="IWO generations timed per setting (0: skip)")
    p.add_argument("--experiment-iterations", type=int, default=1000, help="paper experiment generations (0: skip)")
    p.add_argument("--trials", type=int, default=10, help="paper experiment trials")
    add_data_option(p, "the flight of the paper experiment and the time to a model (default: flight A from the "
                       "shared data if present, else a synthetic 8590-sample flight)")
    p.add_argument("--experiment-data", action=OldForm, old="--experiment-data FILE", new="--data FILE",
                   adopt=adopt_as_data)
    p.add_argument("--host-devices", type=int, default=None,
                   help="split the CPU into this many XLA devices (default: the CPU's cores)")
    p.add_argument("--model-methods", nargs="*", default=["pem", "iwo+polish"],
                   help="methods timed from flight A to a model, compilation included (none: skip)")
    p.add_argument("--model-iterations", type=int, default=1000, help="generations of the timed population methods")
    p.add_argument("--pem-steps", type=int, default=200, help="Levenberg-Marquardt steps of the timed PEM")
    p.add_argument("--model-fit-dt", nargs="+", type=fit_step, default=["full"], metavar="STEP",
                   help="fit steps each timed identify method runs at, once each: full (default), auto (a low-passed "
                        "flight's bandwidth step) or seconds (identify --fit-dt)")
    p.add_argument("--forms", nargs="+", default=["auto"], choices=["auto", "scan", "parallel"],
                   help="time forms the experiment and the time to a model run under, each once (jaxheli.sim.forms)")
    p.add_argument("--form-samples", type=int, nargs="*", default=None,
                   help="flight lengths N of the scan-against-parallel rows (default: --samples; none: skip)")
    p.add_argument("--form-sizes", type=int, nargs="*", default=None,
                   help="population sizes P of the scan-against-parallel rows (default: --sizes)")
    p.add_argument("--costs", action=argparse.BooleanOptionalAction, default=True,
                   help="rates of the costs the engines minimise")
    p.add_argument("--quick", action="store_true", help="tiny settings (a smoke test, seconds)")
    p.add_argument("--out", default="results/bench", help="directory for bench.json, bench.md, throughput.png")
    add_quiet_option(p)
    p.set_defaults(func=_cmd_bench)
    return p


def add_trials_scaling_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``trials-scaling`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser(
        "trials-scaling",
        help="time K IWO trials on one process vs several local jax.distributed processes",
        description="Runs the same K IWO trials (paper cost, synthetic flight) as 1, 2, ... local processes "
        "joined with jax.distributed (CPU, gloo), each process running its share of the trials, and reports "
        "the seconds and the speed-up over one process.",
    )
    p.add_argument("--trials", type=int, default=10, help="IWO trials K")
    p.add_argument("--iterations", type=int, default=50, help="generations per trial")
    p.add_argument("--samples", type=int, default=1000, help="flight length N")
    p.add_argument("--dtype", default="float32", choices=["float32", "float64"])
    p.add_argument("--processes", type=int, nargs="+", default=[1, 2], help="process counts (the first is the base)")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds allowed per process group")
    p.add_argument("--out", default=None, help="also write the result as JSON here")
    p.set_defaults(func=_cmd_trials_scaling)
    return p


def _cmd_bench(args: argparse.Namespace) -> int:
    import jax

    from ..benchmark.report import markdown, write_bench
    from ..benchmark.suite import QUICK, measure

    devices = args.host_devices or os.cpu_count() or 1
    try:
        jax.config.update("jax_num_cpu_devices", devices)
    except RuntimeError:  # JAX already running in this process (e.g. called from Python): keep its devices
        print(f"jaxheli bench: JAX is already initialised; keeping its {jax.local_device_count()} device(s)")
    jax.config.update("jax_enable_x64", True)
    if args.quick:
        for key, value in QUICK.items():
            setattr(args, key, value)
    result = measure(sizes=args.sizes, samples=args.samples, dtypes=args.dtypes, repeats=args.repeats,
                     generations=args.generations, experiment_iterations=args.experiment_iterations,
                     trials=args.trials, experiment_data=args.data, model_methods=args.model_methods,
                     model_iterations=args.model_iterations, pem_steps=args.pem_steps, quick=args.quick,
                     settings={k: v for k, v in vars(args).items() if k != "func"}, forms=args.forms,
                     form_samples=args.form_samples, form_sizes=args.form_sizes, costs=args.costs,
                     model_fit_dts=args.model_fit_dt)
    paths = write_bench(result, args.out)
    print(markdown(result))
    print(f"wrote {', '.join(map(str, paths))}")
    return 0


def _cmd_trials_scaling(args: argparse.Namespace) -> int:
    from ..benchmark.trials_scaling import trials_scaling

    result = trials_scaling(trials=args.trials, iterations=args.iterations, samples=args.samples,
                            dtype=args.dtype, processes=args.processes, timeout=args.timeout)
    print(f"{result['trials']} trials x {result['iterations']} generations, N={result['samples']}, "
          f"{result['dtype']}, {result['cores']} cores")
    for row in result["rows"]:
        print(f"  {row['processes']} process(es): {row['warm_s']:.2f} s warm ({row['cold_s']:.2f} s with compile), "
              f"speed-up {row['speedup']:.2f}x, best-cost difference {row['max_cost_difference']:.2g}")
    if args.out:
        Path(args.out).write_text(json.dumps(result, indent=2))
    return 0
