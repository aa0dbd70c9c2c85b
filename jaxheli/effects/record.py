"""The record of one unmodelled effect (:class:`Effect`) and a registry of them (:class:`Registry`).

An effect is everything the library knows about it, in one place: its stable name, its runs of ``eta`` slots
and their no-effect values (:class:`Group`), its named parameters with units and plausible ranges
(:class:`Param`), the physics it adds to the augmented plant (:class:`Term`) and how the blind check draws
it (:class:`Draw`). The registry lays the groups of all its effects out in one flat vector ``eta[E]`` and
hands each plant stage its terms; :data:`jaxheli.effects.catalogue.EFFECTS` is the library's.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np

from .._types import Array, Float
from ..model import N_INPUTS


class PlantView(Protocol):
    """What a plant term reads of the augmented plant (:class:`~jaxheli.effects.plant.Plant` provides it)."""

    dt: float
    outputs: tuple[str, ...]
    max_delay: int

    def group(self, name: str) -> Array:
        """The ``eta`` entries of one layout group."""
        ...

STAGES: tuple[str, ...] = ("command", "servo", "airframe", "mounting", "reading")
"""Where a plant term acts, in signal order; terms of one stage act in registry order.

- ``command``, ``servo`` (the stick path, :meth:`~jaxheli.effects.plant.Plant.actuate`): ``apply(plant, state,
  sticks, servo) -> (state, sticks)``: the sticks so far [4] to the sticks after the term, ``servo`` being the
  sticks applied over the previous sample; the last output is applied to the rotor.
- ``airframe`` (:meth:`~jaxheli.effects.plant.Plant.advance`): ``apply(plant, state, x, applied) -> (state,
  rate)``: a state-derivative term ``rate[13]`` (state units per s) the plant adds, times ``dt``, to its
  zero-order-hold step.
- ``mounting``, ``reading`` (:meth:`~jaxheli.effects.plant.Plant.measure`): ``apply(plant, y, t) -> y`` on the
  output channels at time ``t`` (s), and its inverse ``invert(plant, y[N, k], t[N]) -> y[N, k]`` for
  :meth:`~jaxheli.effects.plant.Plant.unmeasure`.
"""

STICK: tuple[str, ...] = ("command", "servo")
"""Stages of :meth:`~jaxheli.effects.plant.Plant.actuate`."""
AIRFRAME: tuple[str, ...] = ("airframe",)
"""Stage of :meth:`~jaxheli.effects.plant.Plant.advance`."""
SENSOR: tuple[str, ...] = ("mounting", "reading")
"""Stages of :meth:`~jaxheli.effects.plant.Plant.measure` (and, reversed, of ``unmeasure``)."""


@dataclasses.dataclass(frozen=True)
class Param:
    """One effect parameter: ``eta[slot]``; ``positive`` ones act through ``|eta|`` and are reported so; ``bound``
    is the largest physically plausible magnitude (units of ``unit``); a ``shape`` parameter (a time constant) only
    shapes an effect whose size the others set, so it is never evidence of it; ``tries`` are further start values,
    typical sizes of the effect from which a fit reaches a large one that it stops short of from ``start``
    (:func:`jaxheli.effects.registry.start_rows`), each parameter alone and, with ``together``, all such parameters
    of the effect at once too; a ``nuisance`` parameter is a setting of the predictor rather than of the plant,
    freed in every fit (:func:`jaxheli.effects.registry.nuisance_arrays`)."""

    slot: int
    name: str
    unit: str
    where: str
    start: float
    positive: bool
    bound: float = float("inf")
    shape: bool = False
    tries: tuple[float, ...] = ()
    together: bool = False
    nuisance: bool = False


@dataclasses.dataclass(frozen=True)
class Group:
    """A run of ``size`` slots of ``eta`` (``None``: one per output channel) with no-effect values ``neutral``
    (zeros when empty)."""

    name: str
    size: int | None
    neutral: tuple[float, ...] = ()

    def length(self, outputs: tuple[str, ...]) -> int:
        """Number of slots for a flight with output channels ``outputs``."""
        return len(outputs) if self.size is None else self.size


@dataclasses.dataclass(frozen=True)
class Term:
    """Physics an effect adds to the plant: ``apply`` (and, at a sensor stage, its inverse ``invert``) at
    ``stage`` (one of :data:`STAGES`, whose docstring gives the signatures); ``init(plant)`` gives the state
    the term carries from sample to sample at trim (``None``: stateless)."""

    stage: str
    apply: Callable[..., Any]
    invert: Callable[..., Any] | None = None
    init: Callable[[Any], Any] | None = None


@dataclasses.dataclass(frozen=True)
class Dice:
    """What an injection sampler draws from: the generator after a random ``sign`` (+-1) and stick ``axis``
    (index into :data:`jaxheli.model.INPUT_NAMES`), drawn first for every effect; the flight's output
    channels, their measurement-noise standard deviations and its length ``duration`` (s)."""

    rng: np.random.Generator
    sign: float
    axis: int
    outputs: tuple[str, ...]
    noise: Mapping[str, float]
    duration: float


@dataclasses.dataclass(frozen=True)
class Draw:
    """An injection drawn by an effect's sampler: parameter values by name (the other slots stay at no
    effect), the ``primary`` parameter the blind check scores, and the flight's wind (std m/s, correlation
    time s)."""

    values: Mapping[str, float]
    primary: str
    gust: float = 0.0
    gust_tau: float = 1.0


@dataclasses.dataclass(frozen=True)
class Effect:
    """One candidate unmodelled effect.

    ``name``: stable name. ``groups``: its runs of ``eta`` slots. ``eta_order``: where they sit in ``eta``
    (effects' groups are laid out in increasing ``eta_order``; a new effect takes a number above all others,
    so no existing slot moves). ``params(outputs, at)``: its parameters for a flight with output channels
    ``outputs``, ``at(group, i)`` giving the slot of the ``i``-th entry of one of its groups. ``terms``: the
    physics it adds to the plant (none for an effect that only another component reads). ``inject(dice)``:
    a :class:`Draw` at a random realistic magnitude. ``filtered``: the restart filter reads its parameters (a
    wind, a bias walk), so fitting it whitens the residuals as well as explaining them.
    """

    name: str
    groups: tuple[Group, ...]
    eta_order: int
    params: Callable[[tuple[str, ...], Callable[[str, int], int]], tuple[Param, ...]]
    terms: tuple[Term, ...]
    inject: Callable[[Dice], Draw]
    filtered: bool = False


@dataclasses.dataclass(frozen=True)
class Registry:
    """Effects in their stable order (the order candidates are listed, fitted and reported)."""

    effects: tuple[Effect, ...]

    def __post_init__(self) -> None:
        for what, names in (("effect", [e.name for e in self.effects]),
                            ("group", [g.name for e in self.effects for g in e.groups]),
                            ("eta_order", [e.eta_order for e in self.effects])):
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                raise ValueError(f"Registry: {what} {twice} given twice")
        stray = [(e.name, t.stage) for e in self.effects for t in e.terms if t.stage not in STAGES]
        if stray:
            raise ValueError(f"Registry: unknown stages {stray}; stages are {STAGES}")

    @property
    def names(self) -> tuple[str, ...]:
        """Stable names of the effects."""
        return tuple(e.name for e in self.effects)

    def effect(self, name: str) -> Effect:
        """The effect called ``name``."""
        for e in self.effects:
            if e.name == name:
                return e
        raise ValueError(f"unknown effect {name!r}; candidates are {self.names}")

    def layout(self, outputs: tuple[str, ...]) -> dict[str, slice]:
        """Slices of ``eta`` per group for a flight with output channels ``outputs``."""
        out, start = {}, 0
        for effect in sorted(self.effects, key=lambda e: e.eta_order):
            for group in effect.groups:
                out[group.name] = slice(start, start + group.length(outputs))
                start += group.length(outputs)
        return out

    def size(self, outputs: tuple[str, ...]) -> int:
        """Length ``E`` of ``eta``."""
        return sum(g.length(outputs) for e in self.effects for g in e.groups)

    def no_effect(self, outputs: tuple[str, ...]) -> Float[np.ndarray, "E"]:
        """``eta`` with every effect off: each group at its neutral values."""
        eta = np.zeros(self.size(outputs))
        lay = self.layout(outputs)
        for group in (g for e in self.effects for g in e.groups if g.neutral):
            eta[lay[group.name]] = group.neutral
        return eta

    def params(self, name: str, outputs: tuple[str, ...]) -> tuple[Param, ...]:
        """The parameters effect ``name`` frees for a flight with output channels ``outputs``."""
        effect = self.effect(name)
        lay, own = self.layout(tuple(outputs)), {g.name for g in effect.groups}

        def at(group: str, i: int) -> int:
            if group not in own:
                raise ValueError(f"effect {name!r} addresses group {group!r}, not one of its own {sorted(own)}")
            return lay[group].start + i

        return effect.params(tuple(outputs), at)

    def terms(self, stages: tuple[str, ...]) -> tuple[Term, ...]:
        """The plant terms of ``stages``, in signal order (:data:`STAGES`), then registry order."""
        return tuple(t for s in STAGES if s in stages for e in self.effects for t in e.terms if t.stage == s)

    def inject(
        self, name: str, seed: int, outputs: tuple[str, ...], noise: Mapping[str, float], duration: float
    ) -> tuple[Float[np.ndarray, "E"], Draw]:
        """``(eta, draw)``: effect ``name`` drawn by its sampler from ``numpy``'s generator seeded by ``seed``
        (sign and stick axis first), for a flight with output channels ``outputs`` of measurement-noise
        standard deviations ``noise`` (by channel) lasting ``duration`` s."""
        effect = self.effect(name)
        rng = np.random.default_rng(seed)
        draw = effect.inject(Dice(rng, rng.choice([-1.0, 1.0]), int(rng.integers(N_INPUTS)), tuple(outputs),
                                  noise, duration))
        slots = {p.name: p.slot for p in self.params(name, outputs)}
        eta = self.no_effect(outputs)
        for param, value in draw.values.items():
            eta[slots[param]] = value
        return eta, draw
