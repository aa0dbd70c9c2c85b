"""The library of candidate unmodelled effects: which entries of ``eta`` each one frees, named, with units.

An effect is a set of parameters of the augmented plant (:mod:`jaxheli.effects.plant`), each with a
physical unit, where it acts (an input axis, an output channel, a coupling), a start value for the fit and
the largest magnitude that is physically plausible on a small helicopter (:func:`implausible`); each is
recorded once, with its plant term and blind-check sampler, in :mod:`jaxheli.effects.catalogue`. Stable
names are in :data:`ALL`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from .._types import Float
from .catalogue import EFFECTS
from .plant import no_effect
from .record import Param as Param

ALL: tuple[str, ...] = EFFECTS.names
"""Stable names of the candidate effects."""


def params(effect: str, outputs: tuple[str, ...]) -> tuple[Param, ...]:
    """The parameters ``effect`` frees for a flight with output channels ``outputs``."""
    return EFFECTS.params(effect, outputs)


def box(effect: str, outputs: tuple[str, ...]) -> tuple[Float[np.ndarray, "K"], Float[np.ndarray, "K"]]:
    """``(lower, upper)`` of ``effect``'s parameters: ``[0, bound]`` for those acting through ``|eta|``,
    ``[-bound, bound]`` for signed ones (:attr:`Param.bound`, the physically plausible magnitude)."""
    ps = params(effect, outputs)
    upper = np.array([p.bound for p in ps], dtype=np.float64)
    return np.where([p.positive for p in ps], 0.0, -upper), upper


def candidate_arrays(
    effects: tuple[str, ...] | list[str], outputs: tuple[str, ...], combine: bool = False,
    shape: tuple[int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(index[C, K], start[C, K], lower[C, K], upper[C, K])`` of the effects (or, with ``combine``, of their
    union as one candidate).

    ``index`` holds ``eta`` slots, padded with ``E`` (a dummy slot that acts on nothing); ``start`` the
    start values and ``lower``/``upper`` the box (:func:`box`), all 0 in the padding (a pinned axis).
    ``shape`` pads to at least ``(C, K)``, repeating the last candidate in the extra rows, so that fits of
    different candidate sets share one compiled solver.
    """
    sets = [list(effects)] if combine else [[e] for e in effects]
    rows, width = len(sets), max(sum(len(params(e, outputs)) for e in s) for s in sets)
    if shape is not None:
        rows, width = max(rows, shape[0]), max(width, shape[1])
    sets += [sets[-1]] * (rows - len(sets))
    pad = len(no_effect(outputs))
    index = np.full((rows, width), pad, dtype=np.int32)
    start, lower, upper = (np.zeros((rows, width)) for _ in range(3))
    for c, names in enumerate(sets):
        group = sum((params(e, outputs) for e in names), ())
        index[c, : len(group)] = [p.slot for p in group]
        start[c, : len(group)] = [p.start for p in group]
        lower[c, : len(group)], upper[c, : len(group)] = np.concatenate([box(e, outputs) for e in names], axis=1)
    return index, start, lower, upper


def start_rows(effect: str, outputs: tuple[str, ...]) -> Float[np.ndarray, "R K"]:
    """Start values of ``effect``'s fits, one row per start: the start values; for each further start ``t``
    of :attr:`Param.tries`, the parameters that have one and are tried :attr:`Param.together` at it at once
    (when two or more are), then each parameter that has one alone at it (e.g. a saturation limit at 0.2
    stick on all four axes, then on each axis in turn)."""
    ps = params(effect, outputs)
    first = np.array([p.start for p in ps], dtype=np.float64)
    rows = [first]
    for t in range(max((len(p.tries) for p in ps), default=0)):
        tried = [k for k, p in enumerate(ps) if len(p.tries) > t]
        together = [k for k in tried if ps[k].together]
        for ks in ([together] if len(together) > 1 else []) + [[k] for k in tried]:
            row = first.copy()
            row[ks] = [ps[k].tries[t] for k in ks]
            rows.append(row)
    return np.stack(rows)


def tried_arrays(
    effects: tuple[str, ...] | list[str], outputs: tuple[str, ...], shape: tuple[int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`candidate_arrays` of the single effects with a row per start of each (:func:`start_rows`), and
    ``owner[R]``, the effect (index into ``effects``) each row fits. ``shape`` pads as there, its rows
    counting starts (:func:`joint_shape`); padding rows repeat the last row and its owner."""
    rows, width = shape if shape is not None else (0, 0)
    index, start, lower, upper = candidate_arrays(effects, outputs, shape=(len(effects), width))
    owner, first = [], []
    for c, effect in enumerate(effects):
        for row in start_rows(effect, outputs):
            owner.append(c)
            first.append(np.concatenate([row, start[c, len(row):]]))
    extra = max(0, rows - len(owner))
    owner = np.asarray(owner + owner[-1:] * extra, dtype=np.int32)
    return index[owner], np.stack(first + first[-1:] * extra), lower[owner], upper[owner], owner


def nuisance(outputs: tuple[str, ...]) -> tuple[Param, ...]:
    """The nuisance parameters (:attr:`Param.nuisance`): settings of the predictor every fit frees, the base
    model's alone included (e.g. the restart filter's level), so no candidate is credited for re-tuning them."""
    return tuple(p for e in ALL for p in params(e, outputs) if p.nuisance)


def nuisance_arrays(
    outputs: tuple[str, ...], carried: str | None = None, values: Mapping[str, float] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(slot[S], start[S], lower[S], upper[S])`` of the parameters every row of a fit frees: the ``carried``
    effect's own, when named, then the :func:`nuisance` ones (their box as :func:`box` gives it), started at
    ``values`` (by name) where given."""
    own = () if carried is None else tuple(p for p in params(carried, outputs) if not p.nuisance)
    ps, values = own + nuisance(outputs), {} if values is None else values
    return (np.array([p.slot for p in ps], dtype=np.int32), np.array([values.get(p.name, p.start) for p in ps]),
            np.array([0.0 if p.positive else -p.bound for p in ps]), np.array([p.bound for p in ps]))


def joint_shape(effects: tuple[str, ...] | list[str], outputs: tuple[str, ...], top: int) -> tuple[int, int]:
    """``(R, K)`` that holds both the single fits of ``effects``, a row per start (:func:`tried_arrays`), and
    the joint fit of any ``top`` of them."""
    widths = sorted((len(params(e, outputs)) for e in effects), reverse=True)
    return sum(len(start_rows(e, outputs)) for e in effects), sum(widths[: max(top, 1)])


Z95 = 1.959963984540054
"""Half-width of a two-sided 95 % normal interval, in standard errors."""


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A fitted effect parameter: value and standard error in ``unit``, its 95 % ``interval`` (value +-
    :data:`Z95` standard errors) and where it acts (:attr:`Param.where`)."""

    value: float
    stderr: float
    interval: tuple[float, float]
    unit: str
    where: str

    def to_json(self) -> dict[str, Any]:
        """``{value, stderr, interval, unit, where}``, the interval as a list."""
        return {"value": self.value, "stderr": self.stderr, "interval": list(self.interval), "unit": self.unit,
                "where": self.where}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Estimate:
        """The inverse of :meth:`to_json` (``None``, a non-finite number in JSON, reads as NaN)."""
        return cls(json_number(data["value"]), json_number(data["stderr"]), tuple(map(json_number, data["interval"])),
                   data["unit"], data["where"])


@dataclasses.dataclass(frozen=True)
class Fitted:
    """A fitted effect (or combination) in words and numbers (:func:`report`): its ``params`` by name, the
    axes/channels ``where`` it acts, a ``summary`` sentence, the phrases naming parameters ``at_bound`` and its
    ``evidence_z`` (standard errors from no effect, :func:`evidence`)."""

    params: Mapping[str, Estimate]
    where: tuple[str, ...]
    summary: str
    at_bound: tuple[str, ...]
    evidence_z: float

    def to_json(self) -> dict[str, Any]:
        """``{params, where, summary, at_bound, evidence_z}``, sequences as lists."""
        return {"params": {k: p.to_json() for k, p in self.params.items()}, "where": list(self.where),
                "summary": self.summary, "at_bound": list(self.at_bound), "evidence_z": self.evidence_z}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Fitted:
        """The inverse of :meth:`to_json`."""
        return cls({k: Estimate.from_json(p) for k, p in data["params"].items()}, tuple(data["where"]),
                   data["summary"], tuple(data["at_bound"]), json_number(data["evidence_z"]))


def json_number(value: float | None) -> float:
    """A number read back from JSON: ``None`` (a non-finite number, :func:`~jaxheli._json.json_ready`) as NaN."""
    return float("nan") if value is None else float(value)


def describe(
    effect: str, outputs: tuple[str, ...], value: np.ndarray, stderr: np.ndarray,
) -> tuple[dict[str, Estimate], list[str], str]:
    """``(params, where, sentence)`` of a fitted effect: named :class:`Estimate` values (standard errors, 95 %
    intervals and units), the
    axes/channels whose parameters differ from no-effect by more than two standard errors and by at least a
    quarter of the largest change among parameters of the same unit (else the strongest one), and a
    sentence such as ``"lat input delay 42 +- 6 ms"``."""
    ps = params(effect, outputs)
    value = np.asarray(value, dtype=np.float64)[: len(ps)]
    stderr = np.asarray(stderr, dtype=np.float64)[: len(ps)]
    shown = np.where([p.positive for p in ps], np.abs(value), value)
    neutral = no_effect(outputs)[[p.slot for p in ps]]
    size = np.abs(shown - neutral)
    z = size / np.where(stderr > 0, stderr, np.inf)
    z = np.where(np.isfinite(z), z, 0.0)
    largest = {u: max(size[i] for i in range(len(ps)) if ps[i].unit == u) for u in {p.unit for p in ps}}
    strong = [i for i in range(len(ps)) if z[i] > 2.0 and size[i] >= 0.25 * largest[ps[i].unit]] or [int(np.argmax(z))]
    where = list(dict.fromkeys(ps[i].where for i in strong))
    named = {p.name: Estimate(float(v), float(s), (float(v - Z95 * s), float(v + Z95 * s)), p.unit, p.where)
             for p, v, s in zip(ps, shown, stderr)}
    sentence = "; ".join(_phrase(effect, ps[i], shown[i], stderr[i]) for i in strong)
    return named, where, sentence


AT_BOUND = 1e-3
"""Distance from a bound, as a fraction of the bound, within which a fitted parameter counts as on it."""


def at_bound(effect: str, outputs: tuple[str, ...], value: np.ndarray) -> list[str]:
    """Phrases naming the fitted parameters of ``effect`` on (or past) the physical bound of their box
    (:func:`box`; the no-effect end ``0`` of a ``positive`` one is not a bound), e.g. ``"delay_lat 0.5 s at
    its bound 0.5 s"``; empty if none. ``value`` as fitted (``|value|`` is compared)."""
    ps = params(effect, outputs)
    value = np.abs(np.asarray(value, dtype=np.float64)[: len(ps)])
    return [f"{p.name} {v:.3g} {p.unit} at its bound {p.bound:g} {p.unit}" for p, v in zip(ps, value)
            if not np.isfinite(v) or v >= (1.0 - AT_BOUND) * p.bound]


def filtered(effect: str) -> bool:
    """Whether the restart filter reads a parameter of ``effect`` (or of a part of a combination ``"a+b"``):
    :attr:`~jaxheli.effects.record.Effect.filtered`."""
    return any(EFFECTS.effect(part).filtered for part in effect.split("+"))


def evidence(effect: str, outputs: tuple[str, ...], value: np.ndarray, stderr: np.ndarray) -> float:
    """The fitted effect's distance from no effect in standard errors: the largest ``|value - neutral| /
    stderr`` over its size parameters (``shape`` ones excluded; 0 when no standard error is positive)."""
    ps = params(effect, outputs)
    value = np.asarray(value, dtype=np.float64)[: len(ps)]
    stderr = np.asarray(stderr, dtype=np.float64)[: len(ps)]
    shown = np.where([p.positive for p in ps], np.abs(value), value)
    neutral = no_effect(outputs)[[p.slot for p in ps]]
    z = [abs(v - n) / s for p, v, n, s in zip(ps, shown, neutral, stderr) if not p.shape and s > 0 and np.isfinite(s)]
    return float(max(z, default=0.0))


def report(name: str, outputs: tuple[str, ...], value: np.ndarray, stderr: np.ndarray) -> Fitted:
    """A fitted effect, or a combination ``"a+b"`` (its parts' values in turn), in words and numbers:
    ``params`` and ``where`` (:func:`describe`, merged over the parts), ``summary`` (their sentences, and the
    parameters :func:`at_bound` if any), ``at_bound`` and ``evidence_z`` (the largest part's :func:`evidence`)."""
    named, where, sentence, bound, z, offset = {}, [], [], [], 0.0, 0
    value, stderr = np.asarray(value, dtype=np.float64), np.asarray(stderr, dtype=np.float64)
    for part in name.split("+"):
        n = len(params(part, outputs))
        v, s = value[offset:offset + n], stderr[offset:offset + n]
        p, w, text = describe(part, outputs, v, s)
        named.update(p)
        where += w
        sentence.append(text)
        bound += at_bound(part, outputs, v)
        z = max(z, evidence(part, outputs, v, s))
        offset += n
    if bound:
        sentence.append("on the physical bound: " + ", ".join(bound))
    return Fitted(named, tuple(where), "; ".join(sentence), tuple(bound), z)


def _phrase(effect: str, p: Param, value: float, stderr: float) -> str:
    if p.unit == "s":
        return f"{p.where} {effect.replace('_', ' ')} {p.name.split('_')[0]} {1e3 * value:.0f} +- {1e3 * stderr:.0f} ms"
    return f"{p.where} {effect.replace('_', ' ')} {p.name} {value:.3g} +- {stderr:.2g} {p.unit}"
