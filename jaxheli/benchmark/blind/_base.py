"""A blind trial's base model: what a user identifies on the contaminated training flight (never the truth), in the
box set for the helicopter's class, by PEM or by IWO and its polish."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...data.flight import FlightData
from ...identify import identify
from ...optim.pem import pem
from ...synth.piloted import DEFAULT_OUTPUTS
from ._scenario import BOXES

BASES: tuple[str, ...] = ("pem", "iwo+polish", "default")
"""How a trial's base model is identified on its training flight: PEM (:func:`~jaxheli.optim.pem.pem`), the
paper's IWO on the Pearson cost followed by the output-error polish, or :func:`~jaxheli.identify.identify`'s default
method, as a user of the command line gets it."""


def base_model(train: FlightData, method: str, seed: int, *, pem_steps: int = 100, iterations: int = 1000,
               outputs: tuple[str, ...] = DEFAULT_OUTPUTS, box: str = "hull") -> tuple[np.ndarray, dict[str, Any]]:
    """The base model a user identifies on ``train`` in the box ``box`` (:data:`BOXES`) by ``method``
    (:data:`BASES`): ``(theta, info)``, ``info`` the method and its run (PEM: ``pem_steps`` LM steps; IWO + polish
    and the default: ``iterations`` generations seeded by ``seed``, then the rest of the method)."""
    lower, upper = BOXES[box]
    if method == "pem":
        ident = pem(train, max_steps=pem_steps, outputs=outputs, lower=lower, upper=upper)
        return np.asarray(ident.theta), {"method": method, "steps": ident.n_steps, "success": ident.success,
                                         "rss": ident.rss}
    if method in ("iwo+polish", "default"):
        chosen = {"method": method} if method == "iwo+polish" else {}
        ident = identify(train, **chosen, iterations=iterations, seed=seed, outputs=outputs, lower=lower,
                         upper=upper, progress=False)
        return np.asarray(ident.params), {"method": ident.method, "iterations": iterations,
                                          "seconds": ident.seconds, "search_cost": ident.polish["cost_after"],
                                          "polish_objective": ident.polish["objective_after"]}
    raise ValueError(f"blind trial: unknown base method {method!r}; methods are {BASES}")
