"""Drive a population optimiser: chunked ``lax.scan``, best-cost history, checkpoints, vmapped trials.

A run is ``init`` then ``step`` repeated; :func:`minimize` scans ``chunk`` generations per jitted call
(compiled once per chunk length) and only returns to Python between chunks, to write the checkpoint; the
progress bar moves every generation (a host callback from inside the scan). :func:`minimize_trials` runs K
independent trials in the same scan: ask and tell are vmapped over the trial axis, and the K candidate
batches are flattened into one batch per generation, whose real candidates are scored ``score_batch`` at a time
(:func:`~jaxheli.optim._base.score`; IWO's padding slots are never scored).

``cost_fn`` is closed over by the jitted chunk: pass a pure JAX function of ``thetas`` (an
``eqx.Partial`` or ``eqx.Module`` keeps large arrays such as flight records traced instead of baked
into the program as constants; a plain function is hashed by identity, so reuse the same object to
reuse the compiled chunk).

Checkpoint file (``checkpoint``): a JSON line with the format and the SHA-256 of everything after it, one
JSON header line (optimiser settings, key, iteration, best cost), then ``eqx.tree_serialise_leaves`` of
``(state, history)``; written to a temporary file and moved into place with ``os.replace``, so a kill
leaves the previous or the new checkpoint, never a torn one. A checkpoint whose bytes do not match its
checksum (flipped, edited, empty or truncated) is refused with an error naming it. ``<checkpoint>.json``
holds a copy of the header for people and tools. A resumed run with the same chunk size is bitwise
identical to an uninterrupted one.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from tqdm import tqdm

from .._types import Array, ArrayLike, Float, Int
from .._xla import quick_jit
from ._base import AbstractPopulationOptimizer, Candidates, CostFn, raw_key, score

_FORMAT = "jaxheli-optim-checkpoint-2"
_BARS: list[tqdm] = []
"""Progress bars of the runs in progress (the innermost last), moved by :func:`_tick`."""


class RunResult(eqx.Module):
    """Outcome of :func:`minimize` (no leading axis) or :func:`minimize_trials` (leading trial axis K).

    Attributes:
        best_theta: ``[K?, dim]`` best parameters, physical units.
        best_cost: ``[K?]`` their cost.
        history: ``[K?, iterations]`` best cost after each generation.
        state: the final optimiser state (resume from it with ``optimizer.step``).
        n_evaluations: ``[K?]`` real candidates scored (initial population included).
    """

    best_theta: Float[Array, "*trials dim"]
    best_cost: Float[Array, "*trials"]
    history: Float[Array, "*trials iterations"]
    state: Any
    n_evaluations: Int[Array, "*trials"]


def minimize(
    optimizer: AbstractPopulationOptimizer,
    cost_fn: CostFn,
    key: ArrayLike,
    *,
    iterations: int | None = None,
    chunk: int = 50,
    progress: bool = True,
    checkpoint: str | os.PathLike | None = None,
    resume: bool = False,
) -> RunResult:
    """Run ``optimizer`` on ``cost_fn`` from ``key``.

    Args:
        optimizer: hyperparameters and bounds (e.g. :class:`~jaxheli.optim.iwo.IWO`).
        cost_fn: ``thetas[P, dim] -> costs[P]``, lower is better; NaN/inf count as worst.
        key: PRNG key (typed or raw); the whole run is a deterministic function of it.
        iterations: generations to run (default ``optimizer.iterations``). The optimiser's own schedule
            (e.g. IWO's sigma) is unchanged: to shorten the schedule, set ``iterations`` on the optimiser.
        chunk: generations per jitted scan (and per checkpoint / progress update).
        progress: show a tqdm bar (stderr).
        checkpoint: file to write after every chunk (see the module docstring); ``None`` for none.
        resume: continue from ``checkpoint`` if it exists (its settings and key must match), otherwise
            start afresh; without ``resume`` an existing checkpoint is overwritten. A checkpoint already
            past ``iterations`` is returned as it is.
    """
    return _drive(optimizer, cost_fn, key, False, iterations, chunk, progress, checkpoint, resume)


def minimize_trials(
    optimizer: AbstractPopulationOptimizer,
    cost_fn: CostFn,
    keys: ArrayLike,
    *,
    iterations: int | None = None,
    chunk: int = 50,
    progress: bool = True,
    checkpoint: str | os.PathLike | None = None,
    resume: bool = False,
) -> RunResult:
    """K independent trials, one per key of ``keys[K]``, in one vmapped scan (arguments of :func:`minimize`).

    Trial ``k`` equals ``minimize(optimizer, cost_fn, keys[k])`` bitwise; every generation scores all
    trials' real candidates together (:func:`~jaxheli.optim._base.score`). Results carry a leading trial axis
    (``history[K, iterations]``); the paper's 10 trials for 95 % intervals are ``keys = split(key, 10)``.
    """
    return _drive(optimizer, cost_fn, keys, True, iterations, chunk, progress, checkpoint, resume)


def _drive(
    optimizer: AbstractPopulationOptimizer,
    cost_fn: CostFn,
    key: ArrayLike,
    trials: bool,
    iterations: int | None,
    chunk: int,
    progress: bool,
    checkpoint: str | os.PathLike | None,
    resume: bool,
) -> RunResult:
    total = optimizer.iterations if iterations is None else int(iterations)
    if total < 0 or chunk < 1:
        raise ValueError(f"need iterations >= 0 and chunk >= 1, got {total} and {chunk}")
    key = raw_key(key)
    if key.ndim != (2 if trials else 1):
        raise ValueError(f"expected {'keys[K]' if trials else 'one key'}, got key data of shape {key.shape}")
    settings = _settings(optimizer, key)
    path = None if checkpoint is None else Path(checkpoint)
    if resume and path is not None and path.exists():
        state, history = _load(path, settings, eqx.filter_eval_shape(_initial_state, optimizer, cost_fn, key, trials))
    else:
        state = _init(optimizer, cost_fn, key, trials)
        history = jnp.zeros((0,) + state.best_cost.shape, state.best_cost.dtype)
    done = history.shape[0]
    with tqdm(total=total, initial=min(done, total), disable=not progress, unit="gen") as bar:
        _BARS.append(bar)
        try:
            while done < total:
                n = min(chunk, total - done)
                state, costs = _chunk(optimizer, cost_fn, state, n, trials, progress)
                history = jnp.concatenate([history, costs])
                done += n
                if path is not None:
                    _save(path, settings, state, history, total, chunk)
                jax.effects_barrier()
                bar.set_postfix(best=f"{float(jnp.min(state.best_cost)):.6g}")
        finally:
            _BARS.pop()
    return RunResult(
        best_theta=state.best_theta,
        best_cost=state.best_cost,
        history=history.T if trials else history,
        state=state,
        n_evaluations=state.n_evaluations,
    )


def _flat_cost(optimizer: AbstractPopulationOptimizer, cost_fn: CostFn, candidates: Candidates) -> Float[Array, "K B"]:
    """The ``[K, B]`` candidates of K trials scored as one flat batch (:func:`~jaxheli.optim._base.score`)."""
    k, b = candidates.real.shape
    flat = jax.tree.map(lambda a: a.reshape((k * b,) + a.shape[2:]), candidates)
    return jnp.reshape(score(cost_fn, flat, optimizer.score_batch), (k, b))


def _initial_state(optimizer: AbstractPopulationOptimizer, cost_fn: CostFn, key: Array, trials: bool) -> Any:
    if not trials:
        return optimizer.init(key, cost_fn)
    candidates = jax.vmap(optimizer.init_ask)(key)
    return jax.vmap(optimizer.init_tell)(key, candidates, _flat_cost(optimizer, cost_fn, candidates))


_init = quick_jit(_initial_state)
"""The initial state, compiled on its own for its one call (the generations' scan keeps XLA's defaults)."""


def _step(optimizer: AbstractPopulationOptimizer, cost_fn: CostFn, state: Any, trials: bool) -> Any:
    if not trials:
        return optimizer.step(state, cost_fn)
    candidates = jax.vmap(optimizer.ask)(state)
    return jax.vmap(optimizer.tell)(state, candidates, _flat_cost(optimizer, cost_fn, candidates))


def _tick() -> None:
    """One generation done: move the innermost progress bar."""
    if _BARS:
        _BARS[-1].update(1)


@eqx.filter_jit
def _chunk(
    optimizer: AbstractPopulationOptimizer, cost_fn: CostFn, state: Any, length: int, trials: bool,
    progress: bool = False,
):
    def body(carry, _):
        carry = _step(optimizer, cost_fn, carry, trials)
        if progress:
            jax.debug.callback(_tick)
        return carry, carry.best_cost

    return jax.lax.scan(body, state, None, length=length)


def _settings(optimizer: AbstractPopulationOptimizer, key: Array) -> dict[str, Any]:
    """What a checkpoint must match to be resumed: optimiser type, hyperparameters, key(s)."""
    hyper = {}
    for field in dataclasses.fields(optimizer):
        value = getattr(optimizer, field.name)
        hyper[field.name] = np.asarray(value).tolist() if isinstance(value, (jax.Array, np.ndarray)) else value
    return {"optimizer": type(optimizer).__name__, "hyperparameters": hyper, "key": np.asarray(key).tolist()}


def _save(path: Path, settings: dict[str, Any], state: Any, history: Array, total: int, chunk: int) -> None:
    header = {
        "format": _FORMAT,
        **settings,
        "iteration": int(history.shape[0]),
        "iterations": total,
        "chunk": chunk,
        "best_cost": np.asarray(state.best_cost).tolist(),
        "n_evaluations": np.asarray(state.n_evaluations).tolist(),
    }
    body = io.BytesIO()
    body.write(json.dumps(header).encode() + b"\n")
    eqx.tree_serialise_leaves(body, (state, history))
    seal = json.dumps({"format": _FORMAT, "sha256": hashlib.sha256(body.getvalue()).hexdigest()})
    _replace(path, lambda f: f.write(seal.encode() + b"\n" + body.getvalue()))
    _replace(path.with_name(path.name + ".json"), lambda f: f.write(json.dumps(header, indent=1).encode()))


def _replace(path: Path, write) -> None:
    """Write ``path`` atomically: a temporary file beside it, flushed to disk, then ``os.replace``."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        write(f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _load(path: Path, settings: dict[str, Any], state_like: Any) -> tuple[Any, Array]:
    header, payload = _verified(path)
    differ = sorted(k for k in settings if header.get(k) != settings[k])
    if differ:
        raise ValueError(f"{path}: checkpoint was written with different {differ}; cannot resume")
    cost = state_like.best_cost
    history_like = jax.ShapeDtypeStruct((header["iteration"],) + cost.shape, cost.dtype)
    try:
        return eqx.tree_deserialise_leaves(io.BytesIO(payload), (state_like, history_like))
    except Exception as exc:  # equinox/numpy raise several types on a payload of the wrong layout
        raise ValueError(f"{path}: checkpoint does not hold this run's optimiser state ({exc})") from exc


def _verified(path: Path) -> tuple[dict[str, Any], bytes]:
    """The header and the serialised state of a checkpoint whose checksum holds; ``ValueError`` naming the
    file otherwise (empty, truncated, edited, flipped bytes, another format)."""
    data = path.read_bytes()
    seal_line, _, body = data.partition(b"\n")
    try:
        seal = json.loads(seal_line)
    except (json.JSONDecodeError, UnicodeDecodeError):
        seal = None
    if not isinstance(seal, dict) or seal.get("format") != _FORMAT:
        what = "empty file" if not data else f"format {seal.get('format')!r}" if isinstance(seal, dict) else "no header"
        raise ValueError(f"{path}: not a jaxheli optimiser checkpoint ({what}); delete it or run without --resume")
    if hashlib.sha256(body).hexdigest() != seal.get("sha256"):
        raise ValueError(f"{path}: corrupt checkpoint: its {len(body)} bytes do not match the stored SHA-256 "
                         f"(truncated or changed); delete it or run without --resume")
    header_line, _, payload = body.partition(b"\n")
    return json.loads(header_line), payload
