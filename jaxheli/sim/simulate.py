"""Batched discrete-time simulation of the hover model on a flight's recorded sticks.

One :class:`Simulator` holds a flight's arrays and the simulation settings; calling it on
``theta[..., 40]`` returns the simulated outputs ``[..., N, k]`` in one jitted call (the population is
vmapped, so every candidate's 13-state trajectory runs inside one ``lax.scan``).

Hover models are open-loop unstable, so besides the paper's single long run (``segment=None``) the
simulator offers multiple shooting: every ``segment`` seconds the measured states restart from the
flight, the unmeasured ones are carried over from the previous segment (``reset="carry"``) or zeroed
(``reset="zero"``). The output at a restart sample is the prediction before the restart, so no sample
after the first is copied from the measurement. With ``x0="estimated"`` every run instead starts from the
state that best fits its measured outputs (:mod:`jaxheli.sim.shooting`).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float, Int, Params
from .blocked import Blocks, Plan, blocked_rollout, choose_block, make_plan, population_discrete, run_blocks
from .discretize import Hold, discretize
from .forms import FORMS, TimeForm, choose_form
from .shooting import estimated_outputs, run_bound
from ..data.flight import FlightData
from ..model import FLAPPING, G_SI, MEASURABLE, N_STATES, build_ab, output_indices

InitialState = Literal["zero", "measured", "estimated"]
Reset = Literal["carry", "zero"]
SimMethod = Literal["auto", "scan", "blocked"]


class Simulator(eqx.Module):
    """Simulator of one flight under fixed settings; ``sim(theta) -> outputs[..., N, k]``.

    Build it with :func:`make_simulator`. Arrays are pytree leaves (traced), settings are static.
    """

    inputs: Float[Array, "N 4"]
    measured_states: Float[Array, "N 13"]
    x0: Float[Array, "13"] | None
    dt: float = eqx.field(static=True)
    outputs: tuple[str, ...] = eqx.field(static=True)
    measured_mask: tuple[bool, ...] = eqx.field(static=True)
    g: float = eqx.field(static=True)
    hold: Hold = eqx.field(static=True)
    initial: InitialState | Literal["given"] = eqx.field(static=True)
    segment_samples: int = eqx.field(static=True)
    reset: Reset = eqx.field(static=True)
    method: Literal["scan", "blocked"] = eqx.field(static=True, default="scan")
    block: int = eqx.field(static=True, default=0)
    run_samples: Int[Array, ""] = eqx.field(default_factory=lambda: jnp.asarray(0), converter=jnp.asarray)
    """Estimated initial states: samples between restarts (0: one run), a run-time value so that every run length
    shares one compiled simulation (``segment_samples`` is 0 then)."""
    max_runs: int = eqx.field(static=True, default=1)
    """Estimated initial states: the compiled bound on the number of runs (:func:`~jaxheli.sim.shooting.run_bound`)."""
    time_form: TimeForm = eqx.field(static=True, default="auto")
    """How the recursions in time run: ``"scan"``, ``"parallel"`` or ``"auto"`` (:func:`jaxheli.sim.forms.choose_form`:
    the blocked kernel's block starts and the estimated runs' recursions; the plain scan simulator always scans)."""

    @property
    def restart_samples(self) -> int:
        """Samples between restarts, 0 for one run (read on the host)."""
        return int(self.run_samples) if self.initial == "estimated" else self.segment_samples

    def __call__(self, theta: Params) -> Float[Array, "*batch N k"]:
        theta = jnp.asarray(theta)
        batch = theta.shape[:-1]
        flat = theta.reshape((-1, theta.shape[-1]))
        if self.initial == "estimated":
            y = jax.vmap(functools.partial(estimated_outputs, self))(flat)
        elif self.method == "blocked":
            y = _blocked_outputs(self, flat)
        else:
            y = jax.vmap(self._one)(flat)
        return y.reshape(batch + y.shape[1:])

    def blocks(self, thetas: Float[Array, "P 40"]) -> Blocks:
        """The blocked run of a population (blocked method only): what the rollout and the Pearson sums
        (:mod:`jaxheli.sim.pearson_sums`) both start from."""
        d = population_discrete(thetas, self.g, self.dt, self.hold)
        return run_blocks(
            d,
            self.inputs.astype(d.Ad.dtype),
            self.initial_states(thetas.shape[0], d.Ad.dtype),
            self.measured_states.astype(d.Ad.dtype),
            np.asarray(self.measured_mask),
            self.reset == "carry",
            output_indices(self.outputs),
            self.plan(thetas.shape[0]),
        )

    def plan(self, candidates: int = 1) -> Plan:
        """Layout of the blocks (blocked method only), its block starts in the form :attr:`time_form` resolves to
        for ``candidates`` at once."""
        plan = make_plan(self.inputs.shape[0], self.block, self.segment_samples, self.hold)
        form = choose_form("population", plan.n_blocks, self.time_form,
                           elements=plan.n_blocks * N_STATES * N_STATES * candidates)
        return plan._replace(parallel=form == "parallel")

    def initial_states(self, count: int, dtype) -> Float[Array, "13 P"]:
        """``x0`` for ``count`` candidates, population last."""
        if self.x0 is not None:
            x0 = self.x0.astype(dtype)
        elif self.initial == "measured":
            x0 = self.measured_states[0].astype(dtype)
        else:
            x0 = jnp.zeros(N_STATES, dtype)
        return jnp.broadcast_to(x0[:, None], (N_STATES, count))

    def states(self, theta: Float[Array, "40"]) -> Float[Array, "N 13"]:
        """All 13 simulated states for one parameter vector (for plots and diagnosis)."""
        if self.initial == "estimated":
            raise ValueError("Simulator.states: not available for estimated initial states; give an x0")
        return self._rollout(jnp.asarray(theta), jnp.arange(N_STATES))

    def _one(self, theta: Float[Array, "40"]) -> Float[Array, "N k"]:
        return self._rollout(theta, jnp.asarray(output_indices(self.outputs)))

    def _rollout(self, theta: Float[Array, "40"], idx: Array) -> Array:
        A, B = build_ab(theta, self.g)
        d = discretize(A, B, self.dt, self.hold)
        meas = self.measured_states.astype(d.Ad.dtype)
        mask = jnp.asarray(self.measured_mask)
        if self.x0 is not None:
            x0 = self.x0.astype(d.Ad.dtype)
        elif self.initial == "measured":
            x0 = meas[0]
        else:
            x0 = jnp.zeros(N_STATES, d.Ad.dtype)
        n = self.inputs.shape[0]
        k = jnp.arange(1, n)
        restart = (k % self.segment_samples == 0) if self.segment_samples > 0 else jnp.zeros(n - 1, bool)
        u = self.inputs.astype(d.Ad.dtype)
        keep_unmeasured = 1.0 if self.reset == "carry" else 0.0

        def step(x, inp):
            u0, u1, m1, r1 = inp
            x_next = d.Ad @ x + d.B0 @ u0 + d.B1 @ u1
            restarted = jnp.where(mask, m1, keep_unmeasured * x_next)
            return jnp.where(r1, restarted, x_next), x_next[idx]

        _, ys = jax.lax.scan(step, x0, (u[:-1], u[1:], meas[1:], restart))
        return jnp.concatenate([x0[idx][None, :], ys], axis=0)

    def replace_x0(self, x0: Float[Array, "13"]) -> Simulator:
        """The same simulator started from the given initial state."""
        return dataclasses.replace(self, x0=jnp.asarray(x0), initial="given")

    def configure(
        self,
        *,
        outputs: tuple[str, ...] | list[str],
        g: float = G_SI,
        hold: Hold = "zoh",
        x0: InitialState | Float[np.ndarray, "13"] = "zero",
        segment: float | None = None,
        reset: Reset = "carry",
        method: SimMethod = "auto",
        block: int | None = None,
        time_form: TimeForm | None = None,
    ) -> Simulator:
        """The same flight under other settings (those of :func:`make_simulator`; ``outputs`` are state names;
        ``time_form`` ``None`` keeps the simulator's)."""
        if hold not in ("zoh", "foh"):
            raise ValueError(f"hold must be 'zoh' or 'foh', got {hold!r}")
        if reset not in ("carry", "zero"):
            raise ValueError(f"reset must be 'carry' or 'zero', got {reset!r}")
        if isinstance(x0, str):
            if x0 not in ("zero", "measured", "estimated"):
                raise ValueError(f"x0 must be 'zero', 'measured', 'estimated' or a 13-vector, got {x0!r}")
            x0_arr, initial = None, x0
        else:
            x0_arr = jnp.asarray(x0)
            if x0_arr.shape != (N_STATES,):
                raise ValueError(f"x0 must have shape (13,), got {x0_arr.shape}")
            initial = "given"
        if segment is None:
            seg = 0
        else:
            seg = int(round(segment / self.dt))
            if seg < 1:
                raise ValueError(f"segment must be at least one sample ({self.dt} s), got {segment} s")
        time_form = self.time_form if time_form is None else time_form
        if time_form not in FORMS:
            raise ValueError(f"time_form must be one of {FORMS}, got {time_form!r}")
        if method not in ("auto", "scan", "blocked"):
            raise ValueError(f"method must be 'auto', 'scan' or 'blocked', got {method!r}")
        if method == "blocked" and initial == "estimated":
            raise ValueError("method='blocked' cannot estimate initial states; use 'scan' or 'auto'")
        if method != "scan" and initial != "estimated":
            L = choose_block(seg) if block is None else int(block)
            if L is None or (L < 1 or (seg > 0 and seg % L)):
                if method == "blocked":
                    raise ValueError(
                        f"method='blocked' needs a block length dividing the segment ({seg} samples); "
                        f"got block={block}"
                    )
                method, L = "scan", 0
            else:
                method = "blocked"
        else:
            method, L = "scan", 0
        n = self.inputs.shape[0]
        runs = (seg, 0, run_bound(n, seg, self.dt)) if initial == "estimated" else (0, seg, 1)
        return dataclasses.replace(
            self, x0=x0_arr, outputs=tuple(outputs), g=float(g), hold=hold, initial=initial, segment_samples=runs[1],
            reset=reset, method=method, block=L, run_samples=jnp.asarray(runs[0]), max_runs=runs[2],
            time_form=time_form,
        )

    def describe(self) -> dict[str, object]:
        """The settings in words and numbers, for result files."""
        if self.initial == "estimated":
            runs = f"every {self.restart_samples * self.dt:.4g} s" if self.restart_samples > 0 else "once"
            mode = f"multiple shooting: restart {runs} from the least-squares state (variable projection)"
        elif self.segment_samples > 0:
            mode = (
                f"multiple shooting: restart from measured states every {self.segment_samples * self.dt:.4g} s "
                f"({self.segment_samples} samples), unmeasured states {'carried over' if self.reset == 'carry' else 'zeroed'}"
            )
        else:
            mode = "single open-loop run over the whole record (the paper's simulation)"
        return {
            "mode": mode,
            "segment_s": self.restart_samples * self.dt if self.restart_samples > 0 else None,
            "reset": self.reset if self.segment_samples > 0 else None,
            "hold": self.hold,
            "g": self.g,
            "dt": self.dt,
            "initial_state": self.initial,
            "outputs": list(self.outputs),
            "method": self.method,
            "block": self.block if self.method == "blocked" else None,
        }


def make_simulator(
    flight: FlightData, *, outputs: tuple[str, ...] | list[str] | None = None, **settings: Any
) -> Simulator:
    """Prepare a jittable simulator of ``flight``.

    Args:
        flight: the record whose sticks drive the model and whose outputs seed restarts.
        outputs: channels to return (default: every output the flight has, in its order).
        settings: the keywords of :meth:`Simulator.configure` (defaults there):
            g: gravity in the parameters' unit system, m/s^2.
            hold: ``"zoh"`` (default) or ``"foh"`` (MATLAB ``lsim`` on smooth inputs).
            x0: ``"zero"`` (the paper), ``"measured"`` (measured states at the first sample, the rest zero),
                ``"estimated"`` (every run, the first and each restart, from its least-squares state:
                :mod:`jaxheli.sim.shooting`) or an explicit 13-vector.
            segment: restart interval in seconds (multiple shooting); ``None`` for one long run.
            reset: at a restart, unmeasured states are ``"carry"``-ed over or set to ``"zero"``.
            method: ``"scan"`` (one step per sample), ``"blocked"`` (blocks of ``block`` samples: block-Toeplitz
                products and a scan over block starts, see :mod:`jaxheli.sim.blocked`; equal up to rounding) or
                ``"auto"``: blocked whenever a block length fits the segment length, else scan.
            block: block length in samples for the blocked method (default: chosen by
                :func:`jaxheli.sim.blocked.choose_block`); must divide the segment length.
            time_form: ``"auto"`` (default), ``"scan"`` or ``"parallel"``: how the recursions in time run
                (:mod:`jaxheli.sim.forms`); equal up to rounding.
    """
    names = tuple(flight.output_names if outputs is None else outputs)
    missing = [c for c in names if c not in flight.output_names]
    if missing:
        raise ValueError(f"{flight.source}: output channel(s) {missing} not in the flight {flight.output_names}")
    measured = np.zeros((flight.n_samples, N_STATES))
    state_cols = output_indices(flight.output_names)
    # a and b in the authors' files are stick multiples, not measurements: never restart from them.
    real = [i for i, c in enumerate(flight.output_names) if c in MEASURABLE and c not in FLAPPING]
    measured[:, state_cols[real]] = flight.outputs[:, real]
    mask = np.zeros(N_STATES, bool)
    mask[state_cols[real]] = True
    raw = Simulator(
        inputs=jnp.asarray(flight.inputs), measured_states=jnp.asarray(measured), x0=None, dt=flight.dt,
        outputs=names, measured_mask=tuple(bool(b) for b in mask), g=G_SI, hold="zoh", initial="zero",
        segment_samples=0, reset="carry",
    )
    return raw.configure(outputs=names, **settings)


@eqx.filter_jit
def _blocked_outputs(sim: Simulator, thetas: Array) -> Array:
    return blocked_rollout(sim.blocks(thetas))  # jitted even when called eagerly: the blocked path is many small ops


@eqx.filter_jit
def _run(sim: Simulator, theta: Array) -> Array:
    return sim(theta)


def simulate(theta: Params, flight: FlightData, **options) -> Float[Array, "*batch N k"]:
    """Simulated outputs ``[..., N, k]`` of ``theta[..., 40]`` on ``flight`` (options of :func:`make_simulator`)."""
    return _run(make_simulator(flight, **options), jnp.asarray(theta))
