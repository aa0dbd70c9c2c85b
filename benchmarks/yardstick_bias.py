"""Is the diagnosis's yardstick consistent? The base model re-fitted alone from the *truth* on effect-free flights::

    python benchmarks/yardstick_bias.py [--truth independent] [--seeds 109 157 195] [--segment 2] [--restart filter] [--quiet]

On an effect-free control flight of a blind-check scenario (:func:`jaxheli.benchmark.blind.trial_flights`, kind
``none``: the truth model plus white sensor noise), the reference of :mod:`jaxheli.gap.reference` (the base model
re-fitted alone on the training flight, 60 LM steps a round, the predictor's objective) is started at the truth's
own parameters. A consistent objective keeps it there: its training RSS falls by about the noise the 40 parameters
can fit and the held-out gap stays the truth's. Printed per seed: the training RSS of the truth and of the re-fit,
the validation gap (channel-mean nmse of :func:`jaxheli.gap.fit_effect.score`) of both, and how far the re-fit moved
(Euclidean norm of the parameter change over the box widths). The truth is handed in: a probe of the objective,
not a score of the diagnosis. ``--restart segment`` re-estimates every restart from the segment's own readings
(:func:`jaxheli.gap.segment_restart.restart_correction`). The re-fit's rounds are reported on stderr
(``--quiet``: none).
"""

import argparse

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from jaxheli import configure_xla  # noqa: E402
from jaxheli._progress import reporting  # noqa: E402
from jaxheli.benchmark.blind import BOXES, TRUTHS_SIM, scenario, trial_flights  # noqa: E402
from jaxheli.bounds import Bounds  # noqa: E402
from jaxheli.effects import registry as fx  # noqa: E402
from jaxheli.effects.plant import no_effect  # noqa: E402
from jaxheli.gap.fit_effect import MAX_STEPS, embed, score, with_reference  # noqa: E402
from jaxheli.gap.predictor import RESTARTS  # noqa: E402
from jaxheli.gap.ranking import predictor_pair  # noqa: E402
from jaxheli.gap.reference import REFERENCE_STEPS, refit_alone, theta_box  # noqa: E402
from jaxheli.synth.piloted import DEFAULT_OUTPUTS  # noqa: E402


def probe(truth_sim: str, seed: int, segment: float, restart: str) -> dict[str, float]:
    """The truth's and its re-fit's training RSS and validation gap on control ``seed``, and the distance moved."""
    where = scenario(seed)
    _, train, validate, _, _ = trial_flights(truth_sim, "none", seed, where, duration=30.0, dt=0.05,
                                             outputs=DEFAULT_OUTPUTS)
    outputs = tuple(train.output_names)
    truth = np.asarray(where.theta, np.float64)
    train_pred, validate_pred = predictor_pair(truth, train, validate, segment=segment, smooth=restart == "segment")
    rows = with_reference(*fx.candidate_arrays(fx.ALL, outputs), len(no_effect(outputs)), fx.nuisance_arrays(outputs))
    reference = jax.tree.map(lambda a: a[:1], rows)
    box = theta_box(truth, Bounds(*BOXES["hull"]))
    base = jnp.asarray(no_effect(outputs))
    gap_truth, _ = score(validate_pred, jnp.asarray(truth)[None], base[None])
    fit = refit_alone(train_pred, jnp.asarray(truth), reference, REFERENCE_STEPS * MAX_STEPS, box)
    gap_fit, _ = score(validate_pred, fit.theta[:1], embed(base, reference.index[0], fit.z[0])[None])
    width = np.asarray(box.upper) - np.asarray(box.lower)
    moved = np.abs(np.asarray(fit.theta[0]) - truth) / np.where(width > 0, width, 1.0)
    return {"rss_truth": float(jnp.sum(train_pred.residuals(jnp.asarray(truth), base) ** 2)),
            "rss_refit": float(fit.rss[0]), "gap_truth": float(np.mean(gap_truth)),
            "gap_refit": float(np.mean(gap_fit)), "moved": float(np.linalg.norm(moved)), "style": where.style}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--truth", choices=tuple(TRUTHS_SIM), default="independent", help="truth simulator")
    p.add_argument("--seeds", type=int, nargs="+", default=[109, 157, 195], help="control seeds (scenarios)")
    p.add_argument("--segment", type=float, default=2.0, help="restart interval, s (default 2)")
    p.add_argument("--restart", choices=RESTARTS, default="filter", help="where predictions restart")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    args = p.parse_args()
    configure_xla()
    print("| seed | training flight | training RSS truth -> re-fit | validation gap truth -> re-fit | moved |")
    print("|---|---|---|---|---|")
    for seed in args.seeds:
        with reporting(not args.quiet):
            r = probe(args.truth, seed, args.segment, args.restart)
        print(f"| {seed} | {r['style']} | {r['rss_truth']:.1f} -> {r['rss_refit']:.1f} | "
              f"{r['gap_truth']:.4f} -> {r['gap_refit']:.4f} | {r['moved']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
