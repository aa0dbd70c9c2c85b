"""The library of candidate unmodelled effects: which entries of ``eta`` each one frees, named, with units.

An effect is a set of parameters of the augmented plant (:mod:`jaxheli.effects.plant`), each with a
physical unit, where it acts (an input axis, an output channel, a coupling), a start value for the fit
(away from kinks such as ``|delay| = 0``, where the gradient vanishes) and the largest magnitude that is
physically plausible on a small helicopter (:func:`implausible`). Stable names are in :data:`ALL`.

The plausible ranges, generous on purpose (several times what the blind check injects):

- input delay and servo lag up to 0.5 s (servo and transport delays are 20-150 ms, rotor lags ~0.1 s);
- saturation up to 100 per stick^2, i.e. a limit no tighter than 0.1 of full stick;
- quadratic drag up to 10 1/m; rotor-speed yaw gain up to 50 rad/s^2 per stick, its time constant 3 s;
- gust intensity up to 5 m/s, gust correlation time up to 10 s; with them the restart filter's white
  state noise is cut by a fitted factor ``exp(-|state_noise_cut|)``, without limit (the filter-error method
  estimates the whole process-noise model: once the gusts explain the wind, the filter need not follow the
  sensors as closely as at the base model's tuned level, and the truth of a gusty flight has no white state
  noise at all);
- yaw mounting misalignment up to 0.35 rad (20 deg), gyro scale errors up to 50 %;
- biases and drifts: no limit (they are in the channel's own units).

A fit that leaves its range has absorbed something other than the effect (a mismatch the base model
carries elsewhere), so it is reported but never the verdict.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..model import INPUT_NAMES
from .plant import GYROS, layout, no_effect

ALL: tuple[str, ...] = (
    "input_delay", "actuator_lag", "output_bias_drift", "process_noise", "quadratic_drag",
    "control_saturation", "rotor_speed_coupling", "sensor_misalignment",
)
"""Stable names of the candidate effects."""

_UNITS = {"u": "m/s", "v": "m/s", "w": "m/s", "p": "rad/s", "q": "rad/s", "r": "rad/s", "phi": "rad", "theta": "rad"}


@dataclasses.dataclass(frozen=True)
class Param:
    """One effect parameter: ``eta[slot]``; ``positive`` ones act through ``|eta|`` and are reported so;
    ``bound`` is the largest physically plausible magnitude (units of ``unit``); a ``shape`` parameter (a
    time constant) only shapes an effect whose size the others set, so it is never evidence of it."""

    slot: int
    name: str
    unit: str
    where: str
    start: float
    positive: bool
    bound: float = float("inf")
    shape: bool = False


def params(effect: str, outputs: tuple[str, ...]) -> tuple[Param, ...]:
    """The parameters ``effect`` frees for a flight with output channels ``outputs``."""
    if effect not in ALL:
        raise ValueError(f"unknown effect {effect!r}; candidates are {ALL}")
    lay = layout(tuple(outputs))

    def at(group: str, i: int) -> int:
        return lay[group].start + i

    if effect == "input_delay":
        return tuple(Param(at("delay", i), f"delay_{a}", "s", a, 0.01, True, 0.5) for i, a in enumerate(INPUT_NAMES))
    if effect == "actuator_lag":
        return tuple(Param(at("lag", i), f"lag_{a}", "s", a, 0.01, True, 0.5) for i, a in enumerate(INPUT_NAMES))
    if effect == "control_saturation":
        return tuple(Param(at("sat", i), f"sat_{a}", "1/stick^2", a, 1.0, True, 100.0) for i, a in enumerate(INPUT_NAMES))
    if effect == "quadratic_drag":
        return (Param(at("drag", 0), "Xuu", "1/m", "u", 0.0, False, 10.0),
                Param(at("drag", 1), "Yvv", "1/m", "v", 0.0, False, 10.0))
    if effect == "rotor_speed_coupling":
        return (Param(at("rotor", 0), "rotor_gain", "rad/s^2 per stick", "col->r", 0.1, False, 50.0),
                Param(at("rotor", 1), "rotor_tau", "s", "col->r", 0.5, True, 3.0, shape=True))
    if effect == "process_noise":
        return (Param(at("gust", 0), "gust_std", "m/s", "u,v,w", 0.3, True, 5.0),
                Param(at("gust", 1), "gust_tau", "s", "u,v,w", 1.0, True, 10.0, shape=True),
                Param(at("gust", 2), "state_noise_cut", "ln", "u,v,w", 1.0, True, shape=True))
    if effect == "sensor_misalignment":
        return (Param(at("mis", 0), "yaw_misalignment", "rad", "u-v,p-q,phi-theta", 0.0, False, 0.35),
                *(Param(at("mis", 1 + i), f"scale_{c}", "fraction", c, 0.0, False, 0.5) for i, c in enumerate(GYROS)
                  if c in outputs))
    bias = tuple(Param(at("bias", i), f"bias_{c}", _UNITS.get(c, "-"), c, 0.0, False) for i, c in enumerate(outputs))
    drift = tuple(Param(at("drift", i), f"drift_{c}", f"{_UNITS.get(c, '-')}/s", c, 0.0, False)
                  for i, c in enumerate(outputs))
    return bias + drift


def candidate_arrays(
    effects: tuple[str, ...] | list[str], outputs: tuple[str, ...], combine: bool = False,
    shape: tuple[int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(index[C, K], start[C, K])`` of the effects (or, with ``combine``, of their union as one candidate).

    ``index`` holds ``eta`` slots, padded with ``E`` (a dummy slot that acts on nothing); ``start`` the
    start values (0 in the padding). ``shape`` pads to at least ``(C, K)``, repeating the last candidate in
    the extra rows, so that fits of different candidate sets share one compiled solver.
    """
    groups = [sum((params(e, outputs) for e in effects), ())] if combine else [params(e, outputs) for e in effects]
    rows, width = len(groups), max(len(g) for g in groups)
    if shape is not None:
        rows, width = max(rows, shape[0]), max(width, shape[1])
    groups += [groups[-1]] * (rows - len(groups))
    pad = len(no_effect(outputs))
    index = np.full((rows, width), pad, dtype=np.int32)
    start = np.zeros((rows, width))
    for c, group in enumerate(groups):
        index[c, : len(group)] = [p.slot for p in group]
        start[c, : len(group)] = [p.start for p in group]
    return index, start


def joint_shape(effects: tuple[str, ...] | list[str], outputs: tuple[str, ...], top: int) -> tuple[int, int]:
    """``(C, K)`` that holds both the single fits of ``effects`` and the joint fit of any ``top`` of them."""
    widths = sorted((len(params(e, outputs)) for e in effects), reverse=True)
    return len(widths), sum(widths[: max(top, 1)])


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


def implausible(effect: str, outputs: tuple[str, ...], value: np.ndarray) -> list[str]:
    """Phrases naming the fitted parameters of ``effect`` outside their plausible range (empty if none), such
    as ``"delay_lat 16 s > 0.5 s"``; ``value`` as fitted (``|value|`` is compared)."""
    ps = params(effect, outputs)
    value = np.abs(np.asarray(value, dtype=np.float64)[: len(ps)])
    return [f"{p.name} {v:.3g} {p.unit} > {p.bound:g} {p.unit}" for p, v in zip(ps, value)
            if not np.isfinite(v) or v > p.bound]


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


def _phrase(effect: str, p: Param, value: float, stderr: float) -> str:
    if p.unit == "s":
        return f"{p.where} {effect.replace('_', ' ')} {p.name.split('_')[0]} {1e3 * value:.0f} +- {1e3 * stderr:.0f} ms"
    return f"{p.where} {effect.replace('_', ' ')} {p.name} {value:.3g} +- {stderr:.2g} {p.unit}"
