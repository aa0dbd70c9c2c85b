"""What is solved, apart from how: one flight (or record), its settings and the arrays every engine needs; several
records fitted at once (:class:`Records`).

A :class:`Problem` is built once from a flight and a frozen, serialisable :class:`Settings` (scored channels,
input hold, gravity, restart segment, initial-state rule, population precision, search box). It holds the
simulator, the measured target, each channel's scale and the :class:`~jaxheli.bounds.Bounds`, and every engine
and metric takes it: the population cost, PEM, the polish, the standard errors, :func:`jaxheli.evaluate`
and the initial-state estimate (as optimistix separates the function solved from the solver). A variant
under other simulation settings (:meth:`Problem.variant`, e.g. PEM's restart predictor) needs no flight.

Every array is a pytree leaf and the settings are static, so problems of equally long flights share one
compiled engine.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, Literal

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._types import Array, ArrayLike, Float
from .bounds import Bounds
from .cost import SEARCH_COSTS, SearchCost
from .data.flight import FlightData, FlightDataError, constant_outputs, default_outputs
from .model import G_SI, LOWER, UPPER
from .sim.discretize import Hold
from .sim.population import PopulationCost
from .sim.simulate import InitialState, SimMethod, Simulator, make_simulator

Precision = Literal["float32", "float64"]


@dataclasses.dataclass(frozen=True)
class Settings:
    """How a flight is simulated and scored; frozen and JSON-serialisable (:meth:`to_dict`, :meth:`from_dict`).

    Attributes:
        outputs: scored channels (``None``: the flight's measured channels without a, b).
        hold: ``"zoh"`` or ``"foh"`` input hold.
        g: gravity in the parameters' unit system, m/s^2.
        segment: restart interval, s (multiple shooting); ``None`` for one run from the start (the paper).
        x0: initial state of each run, ``"zero"`` (the paper) or ``"measured"``.
        precision: arithmetic of the population cost (``None``: the session's precision).
        cost: what the population cost scores, ``"pearson"`` (the paper's Eq. 7) or ``"output-error"``
            (:func:`jaxheli.cost.output_error_cost`).
        lower, upper: search box, physical units, :data:`jaxheli.PARAM_NAMES` order (default: the authors').
        simulator: ``"auto"``, ``"scan"`` or ``"blocked"`` (:func:`jaxheli.make_simulator`'s ``method``).
    """

    outputs: tuple[str, ...] | None = None
    hold: Hold = "zoh"
    g: float = G_SI
    segment: float | None = None
    x0: InitialState = "zero"
    precision: Precision | None = None
    cost: SearchCost = "pearson"
    lower: tuple[float, ...] = tuple(LOWER.tolist())
    upper: tuple[float, ...] = tuple(UPPER.tolist())
    simulator: SimMethod = "auto"

    def __post_init__(self) -> None:
        if self.outputs is not None:
            object.__setattr__(self, "outputs", tuple(self.outputs))
        object.__setattr__(self, "lower", tuple(float(v) for v in np.asarray(self.lower).ravel()))
        object.__setattr__(self, "upper", tuple(float(v) for v in np.asarray(self.upper).ravel()))
        if self.precision not in (None, "float32", "float64"):
            raise ValueError(f"precision must be 'float32', 'float64' or None, got {self.precision!r}")
        if self.cost not in SEARCH_COSTS:
            raise ValueError(f"cost must be one of {SEARCH_COSTS}, got {self.cost!r}")

    @property
    def bounds(self) -> Bounds:
        """The search box as :class:`~jaxheli.bounds.Bounds`."""
        return Bounds(np.asarray(self.lower), np.asarray(self.upper))

    def replace(self, **changes: Any) -> Settings:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values."""
        out = dataclasses.asdict(self)
        out["outputs"] = None if self.outputs is None else list(self.outputs)
        out["lower"], out["upper"] = list(self.lower), list(self.upper)
        return out

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Settings:
        """Inverse of :meth:`to_dict` (unknown keys are an error)."""
        unknown = sorted(set(values) - {f.name for f in dataclasses.fields(cls)})
        if unknown:
            raise ValueError(f"Settings: unknown fields {unknown}")
        return cls(**values)


class Source:
    """Where a problem's data came from, for messages. Equal to every other ``Source``, so problems of
    different flights share compiled code."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Source)

    def __hash__(self) -> int:
        return 0

    def __str__(self) -> str:
        return self.text

    def __repr__(self) -> str:
        return f"Source({self.text!r})"


class Problem(eqx.Module):
    """One record under fixed :class:`Settings`: simulator, target ``[N, k]``, channel scales and bounds.

    Build it with :func:`make_problem`. ``scale`` is each measured channel's standard deviation (the
    normalisation of PEM's residuals and of the output-error metrics), ``time`` the sample times from the
    record's start, s.
    """

    sim: Simulator
    target: Float[Array, "N k"]
    scale: Float[Array, "k"]
    time: Float[Array, "N"]
    bounds: Bounds
    settings: Settings = eqx.field(static=True)
    source: Source = eqx.field(static=True)

    @property
    def outputs(self) -> tuple[str, ...]:
        """The scored channels."""
        return self.sim.outputs

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return self.sim.dt

    @property
    def n_samples(self) -> int:
        """Record length ``N``."""
        return int(self.target.shape[0])

    def variant(self, **changes: Any) -> Problem:
        """The same record under changed simulation settings (``hold``, ``g``, ``segment``, ``x0``,
        ``simulator``) or precision, cost and bounds; the scored channels cannot change (they need the flight).
        An initial state given by :meth:`start_from` stays unless ``x0`` changes."""
        if "outputs" in changes and tuple(changes["outputs"]) != self.outputs:
            raise ValueError("Problem.variant: scored channels cannot change; build a new problem from the flight")
        settings = self.settings.replace(**changes)
        given = self.sim.initial == "given" and "x0" not in changes
        sim = self.sim.configure(outputs=self.outputs, g=settings.g, hold=settings.hold,
                                 x0=self.sim.x0 if given else settings.x0,
                                 segment=settings.segment, reset=self.sim.reset, method=settings.simulator)
        return dataclasses.replace(self, sim=sim, bounds=settings.bounds, settings=settings)

    def one_program(self) -> Problem:
        """The same problem keyed for compiling apart from the restart interval of estimated runs (a run-time value
        of the simulator, :attr:`~jaxheli.sim.simulate.Simulator.run_samples`), so a fit at every run length shares
        one compiled program; its settings read ``segment=None`` (what it simulates is unchanged)."""
        if self.sim.initial != "estimated":
            return self
        return dataclasses.replace(self, settings=self.settings.replace(segment=None))

    def start_from(self, x0: Float[ArrayLike, "13"]) -> Problem:
        """The same record simulated from the initial state ``x0[13]`` (its restarts unchanged)."""
        return dataclasses.replace(self, sim=self.sim.replace_x0(x0))

    def population_cost(self) -> PopulationCost:
        """``thetas[P, 40] -> cost[P]``, the settings' search cost in their precision (one jitted call)."""
        return PopulationCost(self.sim, self.target, self.settings.precision, self.settings.cost)

    def describe(self) -> dict[str, Any]:
        """Settings and simulator in words and numbers, for result files."""
        return {"source": str(self.source), "settings": self.settings.to_dict(), "simulator": self.sim.describe()}


def make_problem(flight: FlightData, settings: Settings | None = None, **changes: Any) -> Problem:
    """The :class:`Problem` of ``flight`` under ``settings`` (default :class:`Settings`) with ``changes``; a scored
    channel whose measurement never changes (no scale, no correlation) is an error naming it."""
    settings = (settings or Settings()).replace(**changes)
    names = default_outputs(flight) if settings.outputs is None else settings.outputs
    settings = settings.replace(outputs=names)
    sim = make_simulator(flight, outputs=names, g=settings.g, hold=settings.hold, x0=settings.x0,
                         segment=settings.segment, method=settings.simulator)
    target = flight.select(names).outputs
    flat = [c for c, spread in zip(names, np.ptp(target, axis=0)) if not spread > 0]
    if flat:
        raise ValueError(f"{flight.source}: measured channel(s) {flat} are constant; drop them from outputs")
    return Problem(sim, jnp.asarray(target), jnp.asarray(target.std(axis=0)), jnp.asarray(flight.time - flight.time[0]),
                   settings.bounds, settings, Source(flight.source))


class Records(eqx.Module):
    """Several records fitted at once under one :class:`Settings`: one :class:`Problem` per record (each with its
    own simulator, initial state, target and channel scales); every cost is the sum of the records' costs.

    Build it with :func:`make_records`. It offers what the engines use of a problem (``outputs``, ``settings``,
    ``bounds``, ``n_samples``, :meth:`variant`, :meth:`population_cost`, ...); :func:`parts` gives the records
    of either kind.
    """

    parts: tuple[Problem, ...]

    def __check_init__(self) -> None:
        if not self.parts or len({p.outputs for p in self.parts}) != 1:
            raise ValueError("Records: need at least one record, all scoring the same channels")

    @property
    def outputs(self) -> tuple[str, ...]:
        """The scored channels (every record's)."""
        return self.parts[0].outputs

    @property
    def settings(self) -> Settings:
        """The settings every record shares."""
        return self.parts[0].settings

    @property
    def bounds(self) -> Bounds:
        """The search box."""
        return self.parts[0].bounds

    @property
    def source(self) -> Source:
        """The records' sources, joined."""
        return Source(" + ".join(str(p.source) for p in self.parts))

    @property
    def n_samples(self) -> int:
        """Samples of all records together."""
        return sum(p.n_samples for p in self.parts)

    def variant(self, **changes: Any) -> Records:
        """Every record under changed settings (:meth:`Problem.variant`)."""
        return Records(tuple(p.variant(**changes) for p in self.parts))

    def one_program(self) -> Records:
        """Every record keyed for compiling apart from its run length (:meth:`Problem.one_program`)."""
        return Records(tuple(p.one_program() for p in self.parts))

    def population_cost(self) -> SummedCost:
        """``thetas[P, 40] -> cost[P]``: the sum of the records' search costs."""
        return SummedCost(tuple(p.population_cost() for p in self.parts))

    def describe(self) -> dict[str, Any]:
        """Each record's :meth:`Problem.describe`."""
        return {"source": str(self.source), "records": [p.describe() for p in self.parts]}


class SummedCost(eqx.Module):
    """``thetas[P, 40] -> cost[P]``: the sum of several records' population costs."""

    costs: tuple[PopulationCost, ...]

    def __call__(self, thetas: Array) -> Float[Array, "P"]:
        return sum(cost(thetas) for cost in self.costs)


def parts(problem: Problem | Records) -> tuple[Problem, ...]:
    """The records of a problem: itself, or a :class:`Records`' parts."""
    return problem.parts if isinstance(problem, Records) else (problem,)


def make_records(flights: Sequence[FlightData], settings: Settings | None = None, **changes: Any) -> Records:
    """The :class:`Records` of ``flights`` under ``settings`` with ``changes`` (scored channels: ``outputs``, or
    the first flight's measured channels)."""
    if not flights:
        raise ValueError("make_records: need at least one flight")
    settings = (settings or Settings()).replace(**changes)
    if settings.outputs is None:
        settings = settings.replace(outputs=default_outputs(flights[0]))
    return Records(tuple(make_problem(f, settings) for f in flights))


def as_problem(
    data: FlightData | Sequence[FlightData] | Problem | Records, defaults: dict[str, Any] | None = None,
    **settings: Any,
) -> Problem | Records:
    """The :class:`Problem` (or :class:`Records`) an engine works on.

    A flight becomes the problem of ``Settings(**defaults)`` with ``settings`` (``outputs=None``: the flight's
    measured channels), several flights their :class:`Records`; a problem is taken as it is, or as its
    :meth:`~Problem.variant` under ``settings`` (its scored channels stay; ``defaults`` are not applied to it).
    """
    if isinstance(data, (Problem, Records)):
        if settings.get("outputs") is None or tuple(settings["outputs"]) == data.outputs:
            settings.pop("outputs", None)
        return data.variant(**settings) if settings else data
    if isinstance(data, (list, tuple)) and all(isinstance(f, FlightData) for f in data):
        return make_records(data, Settings(**(defaults or {})), **settings)
    if not isinstance(data, FlightData):
        raise TypeError(f"expected a FlightData or a Problem, got {type(data).__name__}")
    flat = [c for c in settings.get("outputs") or () if c in constant_outputs(data)]
    if flat:
        raise FlightDataError(f"{data.source}: channel(s) {', '.join(flat)} constant (no correlation can be "
                              f"scored); leave them out of outputs")
    return make_problem(data, Settings(**(defaults or {})), **settings)
