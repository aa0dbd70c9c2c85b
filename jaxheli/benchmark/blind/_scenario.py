"""A blind trial's scenario: the truth model, the pilot's excitation style, the sensor-noise level and the effect
strength, cycled with the seed; and the identification boxes a trial's base model is found in."""

from __future__ import annotations

import dataclasses

import numpy as np

from ...model import LOWER, R50_SI, TABLE2, UPPER
from ...synth.excitation import Excitation
from ..truth import wide_truth

STYLES: dict[str, Excitation] = {
    "doublets": Excitation("3211", amplitude=(0.2, 0.2, 0.2, 0.2), unit=0.3),
    "sweep": Excitation("sweep", amplitude=(0.15, 0.15, 0.15, 0.15), band=(0.3, 3.0), fade=0.5),
    "regulation": Excitation("mixed", amplitude=(0.04, 0.04, 0.04, 0.04), unit=0.15, band=(0.3, 3.0), fade=0.5),
}
"""Pilot/excitation styles of the training flight: 3-2-1-1 doublets, frequency sweeps, and the pilot
regulating hover with only faint stick excitation on top (the LQR pilot flies every style)."""

VALIDATE_EXCITATION = Excitation("3211", amplitude=(0.25, 0.25, 0.25, 0.25), unit=0.35)

TRUTHS: tuple[str, ...] = ("table2", "r50", "table2~", "r50~")
"""Truth models: the paper's Table 2 (TREX 550), Mettler's R-50 in SI, and each perturbed by up to +-30 %."""

TRUTH_CLASSES: dict[str, tuple[str, ...]] = {"narrow": TRUTHS, "wide": ("table2+", "r50+")}
"""Classes of truth models: ``narrow`` (:data:`TRUTHS`), or ``wide``: each reference perturbed by up to +-30 % with
the couplings the authors' box pins or bounds tightly drawn at the sizes real rotorcraft have them
(:func:`~jaxheli.benchmark.truth.wide_truth`), so a base model identified in that box is wrong somewhere."""

NOISES: tuple[float, ...] = (1.0, 2.0)
"""Sensor-noise levels, multiples of :data:`~jaxheli.synth.piloted.DEFAULT_NOISE`."""

STRENGTHS: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0)
"""Effect strengths: the registry sampler's size parameters times these (time constants, which only shape an
effect, are not scaled), kept within 80 % of each parameter's physical bound."""


def _hull(*models: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = np.minimum.reduce([LOWER, *(np.minimum(0.5 * m, 2.0 * m) for m in models)])
    hi = np.maximum.reduce([UPPER, *(np.maximum(0.5 * m, 2.0 * m) for m in models)])
    return lo, hi


BOX = _hull(TABLE2, R50_SI)
"""``(lower, upper)``, the identification box of every trial by default: the authors' TREX box widened to hold half
to twice each Table 2 and R-50 parameter (so both classes, perturbed by 30 %, lie inside; ``Nw``, pinned in the TREX
box, is freed): what a user sets for a class of helicopter, not the truth."""

BOXES: dict[str, tuple[np.ndarray, np.ndarray]] = {"hull": BOX, "authors": (LOWER, UPPER)}
"""Identification boxes of the blind check: :data:`BOX` (``hull``), or the command line's default, the authors' TREX
box (``authors``), which the R-50 truths leave (``Mu``, ``Mv``, ``Nv`` beyond it, ``Nw`` pinned at 0): there the
diagnosis must name the base model's structure (:mod:`jaxheli.gap.structure`), not an effect."""


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A trial's truth model (name, parameters), training style, noise multiple and effect strength."""

    truth: str
    theta: np.ndarray
    style: str
    noise: float
    strength: float


def scenario(seed: int, truths: str = "narrow") -> Scenario:
    """The scenario of trial ``seed`` with a truth of the class ``truths`` (:data:`TRUTH_CLASSES`): any 96 (``wide``:
    48) consecutive seeds meet every combination of the class's truths, :data:`STYLES`, :data:`NOISES` and
    :data:`STRENGTHS` once, and a few consecutive seeds already differ in all four (the combination index steps by
    37, prime to both); the perturbations of the ``~`` and ``+`` truths are drawn from ``seed`` (``~``: uniform
    factors 0.7-1.3; ``+``: :func:`~jaxheli.benchmark.truth.wide_truth`)."""
    if truths not in TRUTH_CLASSES:
        raise ValueError(f"blind scenario: unknown truth class {truths!r}; classes are {tuple(TRUTH_CLASSES)}")
    names = TRUTH_CLASSES[truths]
    sizes = (len(names), len(STYLES), len(NOISES), len(STRENGTHS))
    code = (37 * seed) % int(np.prod(sizes))
    i, j, k, m = (code // int(np.prod(sizes[:n])) % sizes[n] for n in range(4))
    truth = names[i]
    theta = np.array(TABLE2 if truth.startswith("table2") else R50_SI)
    rng = np.random.default_rng(1_000_003 + seed)
    if truth.endswith("~"):
        theta = theta * rng.uniform(0.7, 1.3, theta.size)
    if truth.endswith("+"):
        theta = wide_truth(theta, rng)
    return Scenario(truth, theta, tuple(STYLES)[j], NOISES[k], STRENGTHS[m])
