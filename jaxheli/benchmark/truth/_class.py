"""Truth hover models from a class wider than the authors' box: a reference helicopter's 40 parameters perturbed, with
the couplings that box pins or bounds tightly (heave into roll, pitch and yaw, speed into pitch and yaw, pedal into
side force, collective into pitch) at the sizes real rotorcraft have them.

The authors' TREX box pins ``Lw Mw Nw Yped Mcol`` at 0 and bounds ``Mu Mv`` to +-0.1 and ``Nv`` to 0-0.01; a
base model identified in that box is wrong the way a user's is whenever the aircraft has these couplings.
"""

from __future__ import annotations

import numpy as np

from ...model import LOWER, PARAM_NAMES, UPPER

COUPLINGS: dict[str, tuple[float, float]] = {
    "Lw": (0.05, 0.3), "Mw": (0.05, 0.3), "Nw": (0.5, 3.0), "Mu": (0.12, 0.4), "Mv": (0.12, 0.4),
    "Nv": (0.2, 1.5), "Yped": (0.2, 1.5), "Mcol": (0.5, 3.0),
}
"""Magnitude ranges of the drawn couplings, each with a random sign: ``Lw Mw`` (rad/s^2 per m/s), ``Nw`` (rad/s^2
per m/s), ``Mu Mv Nv`` (rad/s^2 per m/s), ``Yped`` (m/s^2 per stick), ``Mcol`` (rad/s^2 per stick). Every draw lies
outside the authors' box."""

SPREAD = 0.3
"""Every other parameter is the reference's times a uniform factor in ``1 +- SPREAD``."""


def wide_truth(reference: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A truth of the wide class about the 40 parameters ``reference``: each parameter times ``U(1 - SPREAD,
    1 + SPREAD)``, then every coupling of :data:`COUPLINGS` drawn afresh in its range with a random sign."""
    theta = np.asarray(reference, dtype=np.float64) * rng.uniform(1.0 - SPREAD, 1.0 + SPREAD, len(PARAM_NAMES))
    for name, (low, high) in COUPLINGS.items():
        theta[PARAM_NAMES.index(name)] = rng.choice([-1.0, 1.0]) * rng.uniform(low, high)
    return theta


def outside_box(theta: np.ndarray) -> tuple[str, ...]:
    """Names of the parameters of ``theta`` outside the authors' box (``model.LOWER`` .. ``model.UPPER``)."""
    theta = np.asarray(theta)
    return tuple(n for n, v, lo, hi in zip(PARAM_NAMES, theta, LOWER, UPPER) if v < lo or v > hi)
