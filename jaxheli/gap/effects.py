"""The library of candidate unmodelled effects: which entries of ``eta`` each one frees, named, with units.

An effect is a set of parameters of the augmented plant (:mod:`jaxheli.gap.augmented`), each with a
physical unit, where it acts (an input axis, an output channel, a coupling) and a start value for the fit
(away from kinks such as ``|delay| = 0``, where the gradient vanishes). Stable names are in :data:`ALL`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..model import INPUT_NAMES
from .augmented import GYROS, layout, no_effect

ALL: tuple[str, ...] = (
    "input_delay", "actuator_lag", "output_bias_drift", "process_noise", "quadratic_drag",
    "control_saturation", "rotor_speed_coupling", "sensor_misalignment",
)
"""Stable names of the candidate effects."""

_UNITS = {"u": "m/s", "v": "m/s", "w": "m/s", "p": "rad/s", "q": "rad/s", "r": "rad/s", "phi": "rad", "theta": "rad"}


@dataclasses.dataclass(frozen=True)
class Param:
    """One effect parameter: ``eta[slot]``; ``positive`` ones act through ``|eta|`` and are reported so."""

    slot: int
    name: str
    unit: str
    where: str
    start: float
    positive: bool


def params(effect: str, outputs: tuple[str, ...]) -> tuple[Param, ...]:
    """The parameters ``effect`` frees for a flight with output channels ``outputs``."""
    if effect not in ALL:
        raise ValueError(f"unknown effect {effect!r}; candidates are {ALL}")
    lay = layout(tuple(outputs))

    def at(group: str, i: int) -> int:
        return lay[group].start + i

    if effect == "input_delay":
        return tuple(Param(at("delay", i), f"delay_{a}", "s", a, 0.01, True) for i, a in enumerate(INPUT_NAMES))
    if effect == "actuator_lag":
        return tuple(Param(at("lag", i), f"lag_{a}", "s", a, 0.01, True) for i, a in enumerate(INPUT_NAMES))
    if effect == "control_saturation":
        return tuple(Param(at("sat", i), f"sat_{a}", "1/stick^2", a, 1.0, True) for i, a in enumerate(INPUT_NAMES))
    if effect == "quadratic_drag":
        return (Param(at("drag", 0), "Xuu", "1/m", "u", 0.0, False),
                Param(at("drag", 1), "Yvv", "1/m", "v", 0.0, False))
    if effect == "rotor_speed_coupling":
        return (Param(at("rotor", 0), "rotor_gain", "rad/s^2 per stick", "col->r", 0.1, False),
                Param(at("rotor", 1), "rotor_tau", "s", "col->r", 0.5, True))
    if effect == "process_noise":
        return (Param(at("gust", 0), "gust_std", "m/s", "u,v,w", 0.3, True),
                Param(at("gust", 1), "gust_tau", "s", "u,v,w", 1.0, True))
    if effect == "sensor_misalignment":
        return (Param(at("mis", 0), "yaw_misalignment", "rad", "u-v,p-q,phi-theta", 0.0, False),
                *(Param(at("mis", 1 + i), f"scale_{c}", "fraction", c, 0.0, False) for i, c in enumerate(GYROS)
                  if c in outputs))
    bias = tuple(Param(at("bias", i), f"bias_{c}", _UNITS.get(c, "-"), c, 0.0, False) for i, c in enumerate(outputs))
    drift = tuple(Param(at("drift", i), f"drift_{c}", f"{_UNITS.get(c, '-')}/s", c, 0.0, False)
                  for i, c in enumerate(outputs))
    return bias + drift


def candidate_arrays(
    effects: tuple[str, ...] | list[str], outputs: tuple[str, ...], combine: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """``(index[C, K], start[C, K])`` of the effects (or, with ``combine``, of their union as one candidate).

    ``index`` holds ``eta`` slots, padded with ``E`` (a dummy slot that acts on nothing); ``start`` the
    start values (0 in the padding).
    """
    groups = [sum((params(e, outputs) for e in effects), ())] if combine else [params(e, outputs) for e in effects]
    width = max(len(g) for g in groups)
    pad = len(no_effect(outputs))
    index = np.full((len(groups), width), pad, dtype=np.int32)
    start = np.zeros((len(groups), width))
    for c, group in enumerate(groups):
        index[c, : len(group)] = [p.slot for p in group]
        start[c, : len(group)] = [p.start for p in group]
    return index, start


def describe(effect: str, outputs: tuple[str, ...], value: np.ndarray, stderr: np.ndarray) -> tuple[dict, list, str]:
    """``(params, where, sentence)`` of a fitted effect: named values with standard errors and units, the
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
    named = {p.name: {"value": float(v), "stderr": float(s), "unit": p.unit, "where": p.where}
             for p, v, s in zip(ps, shown, stderr)}
    sentence = "; ".join(_phrase(effect, ps[i], shown[i], stderr[i]) for i in strong)
    return named, where, sentence


def _phrase(effect: str, p: Param, value: float, stderr: float) -> str:
    if p.unit == "s":
        return f"{p.where} {effect.replace('_', ' ')} {p.name.split('_')[0]} {1e3 * value:.0f} +- {1e3 * stderr:.0f} ms"
    return f"{p.where} {effect.replace('_', ' ')} {p.name} {value:.3g} +- {stderr:.2g} {p.unit}"
