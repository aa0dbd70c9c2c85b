"""Wall time of ``jaxheli.gap.diagnose`` on one flight pair of the independent truth simulator (issue 34's
diagnosis timings)::

    python benchmarks/diagnose_time.py [--kind logger_delay] [--seed 3] [--duration 60] [--dt 0.02] [--max-steps 15] [--native] [--cache] [--quiet]

The pair is the blind check's (:func:`jaxheli.benchmark.independent.independent_trial`, scenario of ``--seed``),
the base model a 100-step PEM fit in the authors' box, as a user would identify it; the time printed is the
diagnosis's alone (float64, compile included; at the thresholds' step, the flights low-passed and resampled to it,
or ``--native`` at the flights' own), then its verdict; progress lines go to stderr (``--quiet``: none).
``--cache`` reads and writes compiled programs in the command line's cache (:func:`jaxheli._compile_cache.use_compile_cache`): run it
twice for the time of a user's second diagnosis.
"""

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)

from jaxheli import configure_xla  # noqa: E402
from jaxheli._compile_cache import use_compile_cache  # noqa: E402
from jaxheli._progress import reporting  # noqa: E402
from jaxheli.benchmark.blind import base_model, scenario  # noqa: E402
from jaxheli.benchmark.independent import independent_trial  # noqa: E402
from jaxheli.gap.diagnose import diagnose  # noqa: E402
from jaxheli.gap.fit_effect import MAX_STEPS  # noqa: E402
from jaxheli.gap.prepare import SAMPLE_S  # noqa: E402
from jaxheli.synth.piloted import DEFAULT_OUTPUTS  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kind", default="logger_delay", help="withheld effect of the independent simulator")
    p.add_argument("--seed", type=int, default=3, help="design seed of the scenario (default 3)")
    p.add_argument("--duration", type=float, default=60.0, help="flight length, s (default 60)")
    p.add_argument("--dt", type=float, default=0.02, help="sample time, s (default 0.02: 50 Hz)")
    p.add_argument("--max-steps", type=int, default=MAX_STEPS,
                   help=f"LM steps per candidate fit (default {MAX_STEPS}, the diagnosis's)")
    p.add_argument("--native", action="store_true",
                   help="diagnose at the flights' own step (default: the thresholds' step, jaxheli.gap.prepare.SAMPLE_S)")
    p.add_argument("--cache", action="store_true",
                   help="read and write compiled programs in $JAXHELI_CACHE (default: compile afresh)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    args = p.parse_args()
    configure_xla()
    if args.cache:
        print(f"compilation cache: {use_compile_cache()}")
    where = scenario(args.seed)
    trial = independent_trial(args.kind, args.seed, where.theta, style=where.style, noise=where.noise,
                              strength=where.strength, duration=args.duration, dt=args.dt, outputs=DEFAULT_OUTPUTS)
    with reporting(not args.quiet):
        theta, _ = base_model(trial.train, "pem", args.seed, box="authors")
        t0 = time.perf_counter()
        found = diagnose(theta, trial.train, trial.validate, max_steps=args.max_steps,
                         dt=None if args.native else SAMPLE_S)
    step = found.flights["train"].dt
    print(f"diagnose: {time.perf_counter() - t0:.1f} s ({args.duration:g} s at {1 / args.dt:g} Hz, diagnosed at "
          f"{1 / step:g} Hz, truth {where.truth}, {args.kind} withheld, {args.max_steps} LM steps per fit)")
    print(f"verdict: {found.attribution.verdict}")


if __name__ == "__main__":
    main()
