"""The paper's whole experiment end to end: K trials x G generations of IWO on one flight, timed."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from ..data.flight import FlightData
from ..model import LOWER, UPPER
from ..optim.iwo import IWO
from ..optim.run import minimize_trials
from ..sim.population import PopulationCost
from ..sim.simulate import make_simulator


def iwo_buffer_slots(opt: IWO, trials: int = 1) -> int:
    """Slots of IWO's fixed seed buffer over ``trials`` runs of ``opt`` (initial population included): what a kernel
    that scored the buffer's padding too would score."""
    return trials * (opt.iterations * opt.max_population * opt.max_seeds + opt.initial_population)


def paper_experiment(
    flight: FlightData,
    *,
    trials: int = 10,
    iterations: int = 1000,
    dtype: jnp.dtype = jnp.float32,
    chunk: int = 100,
    seed: int = 0,
    progress: bool = False,
    time_form: str = "auto",
) -> dict[str, object]:
    """Run IWO with the paper's settings (``trials`` vmapped trials of ``iterations`` generations, zero
    initial state, Pearson cost on every output channel of ``flight``) and time it, compilation included.

    ``time_form``: how the kernel's block starts run (:func:`jaxheli.sim.forms.choose_form`). Returns the form used,
    wall seconds, candidate evaluations (the real seeds, the only candidates scored, and what a per-candidate
    loop would score too), the slots of IWO's fixed seed buffer, evaluations per second and each trial's best cost.
    """
    sim = make_simulator(flight, time_form=time_form)
    cost = PopulationCost(sim, jnp.asarray(flight.outputs, dtype), jnp.dtype(dtype).name)
    opt = IWO(LOWER, UPPER, iterations=iterations)
    keys = jax.random.split(jax.random.key(seed), trials)
    t0 = time.perf_counter()
    result = minimize_trials(opt, cost, keys, chunk=min(chunk, iterations), progress=progress)
    best = np.asarray(jax.block_until_ready(result.best_cost))
    seconds = time.perf_counter() - t0
    scored = int(np.sum(np.asarray(result.n_evaluations)))
    return {
        "flight": flight.source,
        "samples": flight.n_samples,
        "channels": list(flight.output_names),
        "trials": trials,
        "iterations": iterations,
        "dtype": jnp.dtype(dtype).name,
        "method": sim.method,
        "time_form": time_form,
        "resolved_form": "parallel" if sim.method == "blocked" and sim.plan(40).parallel else "scan",
        "seconds": seconds,
        "evaluations": scored,
        "buffer_slots": iwo_buffer_slots(opt, trials),
        "evaluations_per_s": scored / seconds,
        "best_cost": best.tolist(),
    }
