"""Process noise named last: the effects ranked again beyond it when it leads the ranking.

Process noise (gusts through the velocity derivatives, with the restart filter's white state noise) is the
filter-error method's model of whatever the base model leaves unexplained, a wrong structure's misfit included, so
it can out-shrink the effect that caused the gap. When it leads, the effects the restart filter does not read are
ranked again with its gusts freed in every fit (:func:`beyond_noise`), and each other disturbance the filter
estimates (a bias's walk) that is significant in the box is tested the other way: the noise ranked beyond it
(:func:`noise_beyond`). What the verdict makes of both: :func:`~jaxheli.gap.verdict.past_noise`."""

from __future__ import annotations

import numpy as np

from .._progress import stage
from ..bounds import Bounds
from ..effects import registry as fx
from .candidate_records import Entry
from .candidates import ranked
from .predictor import Predictor
from .reference import theta_box
from .verdict import NOISE

ROWS = 4
"""A re-check's candidate rows are padded to a multiple of this, so its solver compiles for few batch shapes."""


def padded_rows(owner: np.ndarray, chosen: list[int]) -> np.ndarray:
    """The rows of the candidates ``chosen`` (``owner[r]``: row ``r``'s candidate), the last repeated up to a
    multiple of :data:`ROWS`."""
    rows = np.flatnonzero(np.isin(owner, chosen))
    return np.r_[rows, np.full(-len(rows) % ROWS, rows[-1])]


def _carried_ranking(
    train: Predictor, validate: Predictor, labels: list[str], arrays: tuple[np.ndarray, ...], owner: np.ndarray,
    chosen: list[int], carried: Entry, max_steps: int, min_shrink: float, box: Bounds,
) -> list[Entry]:
    """The candidates ``chosen`` (indices into ``labels``) ranked with ``carried``'s effect freed in every row, the
    reference's included, from its fit (its base parameters, effect and nuisance values), in ``box`` widened to hold
    them."""
    rows = padded_rows(owner, chosen)
    return ranked(train, validate, carried.theta, [labels[c] for c in chosen], tuple(a[rows] for a in arrays),
                  np.searchsorted(chosen, owner[rows]), max_steps, min_shrink, theta_box(carried.theta, box),
                  carried=carried).entries


def beyond_noise(
    train: Predictor, validate: Predictor, labels: list[str], arrays: tuple[np.ndarray, ...], owner: np.ndarray,
    noise: Entry, max_steps: int, min_shrink: float, box: Bounds,
) -> tuple[Entry, ...]:
    """The candidates ``labels`` (rows ``arrays``, candidate ``owner[r]`` for row ``r``) that the restart filter
    does not read (:func:`~jaxheli.effects.registry.filtered`), ranked beyond the ``noise`` entry's gusts
    (:func:`_carried_ranking`). A second disturbance the filter estimates (a bias's walk) is not ranked beyond the
    first: on turbulence, the walk took up the rotational gusts the wind model lacks (:func:`noise_beyond` tests
    it the other way)."""
    chosen = [c for c, name in enumerate(labels) if not fx.filtered(name)]
    with stage(f"re-check of {len(chosen)} effects beyond process noise ({noise.fitted.summary})") as now:
        again = _carried_ranking(train, validate, labels, arrays, owner, chosen, noise, max_steps, min_shrink, box)
        now.outcome = f"significant beyond it: {', '.join(e.effect for e in again if e.significant) or 'none'}"
    return tuple(again)


def noise_beyond(
    train: Predictor, validate: Predictor, labels: list[str], arrays: tuple[np.ndarray, ...], owner: np.ndarray,
    rivals: list[Entry], max_steps: int, min_shrink: float, box: Bounds,
) -> dict[str, Entry]:
    """Process noise (among ``labels``, rows ``arrays`` by ``owner``) ranked beyond each of the ``rivals``
    (entries of other disturbances the filter estimates, significant in the box), by rival name: a rival the
    noise adds nothing beyond explains what the noise did."""
    found = {}
    for rival in rivals:
        with stage(f"re-check of process noise beyond {rival.effect} ({rival.fitted.summary})") as now:
            entry = _carried_ranking(train, validate, labels, arrays, owner, [labels.index(NOISE)], rival,
                                     max_steps, min_shrink, box)[0]
            now.outcome = (f"{entry.shrink_pct:.1f} +- {entry.shrink_se_pct:.1f} %, "
                           f"{'significant' if entry.significant else 'not significant'}")
        found[rival.effect] = entry
    return found
