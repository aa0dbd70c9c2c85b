"""The hover model's modes: eigenvalues of ``A`` (1/s), each named by the states that take part in it.

A mode's share of each state is its participation factor ``p_i = |w_i v_i|`` (``v`` the right, ``w`` the left
eigenvector, normalised to sum 1; Perez-Arriaga, Verghese and Schweppe 1982). Unlike the entries of ``v`` it does
not depend on the states' units: rescaling a state (m/s to ft/s, rad to deg) leaves it unchanged, so velocities,
rates, angles and flapping compare directly. The state groups that name a mode (the largest summed share wins):

- hover cubic / phugoid: ``u v phi theta`` (the slow fuselage translation and attitude);
- rotor-body: ``p q a b`` (roll and pitch rate with the main rotor's flapping);
- stabilizer bar: ``c d``;
- yaw-heave: ``w r r_fb`` (heave, yaw rate and the yaw gyro's feedback state).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.linalg

from ._types import Float
from .model import G_SI, STATE_NAMES, build_ab

GROUPS: dict[str, tuple[str, ...]] = {
    "hover cubic / phugoid": ("u", "v", "phi", "theta"),
    "rotor-body": ("p", "q", "a", "b"),
    "stabilizer bar": ("c", "d"),
    "yaw-heave": ("w", "r", "r_fb"),
}
"""The physical name of a mode from the states dominating it (every state in exactly one group)."""

AXES: dict[str, tuple[str, ...]] = {
    "longitudinal": ("u", "q", "theta", "a", "c"),
    "lateral": ("v", "p", "phi", "b", "d"),
}
"""Axis of a fuselage, rotor or bar mode: the one holding over two thirds of its participation (else coupled)."""

DOMINANT = 0.1
"""Share of participation above which a state is listed among a mode's dominant states."""


@dataclasses.dataclass(frozen=True)
class Mode:
    """One mode of the continuous-time model (one entry per complex-conjugate pair).

    Attributes:
        eigenvalue: ``sigma + j omega_d``, 1/s (the member with ``omega_d >= 0`` of a pair).
        name: physical name (:data:`GROUPS`, with the axis or heave/yaw where one dominates).
        participation: each state's share (:data:`jaxheli.model.STATE_NAMES` order), sums to 1.
        shape: the right eigenvector's magnitudes over its largest (model units; zero where the mode never shows).
    """

    eigenvalue: complex
    name: str
    participation: Float[np.ndarray, "13"]
    shape: Float[np.ndarray, "13"]

    @property
    def states(self) -> tuple[str, ...]:
        """States with a share above :data:`DOMINANT`, largest first."""
        order = np.argsort(-self.participation, kind="stable")
        return tuple(STATE_NAMES[i] for i in order if self.participation[i] > DOMINANT)

    def seen_in(self, states: tuple[str, ...] | list[str]) -> bool:
        """Whether the mode shows in any of ``states`` (its right eigenvector not zero there, to rounding)."""
        return any(self.shape[STATE_NAMES.index(s)] > 1e-9 for s in states)

    @property
    def oscillatory(self) -> bool:
        """A complex pair (``omega_d > 0``)."""
        return self.eigenvalue.imag > 0

    @property
    def natural_frequency(self) -> float:
        """``omega_n = |lambda|``, rad/s."""
        return abs(self.eigenvalue)

    @property
    def damping(self) -> float:
        """``zeta = -sigma / omega_n`` (negative: unstable; +-1 for a real root)."""
        return -self.eigenvalue.real / self.natural_frequency if self.natural_frequency > 0 else 1.0

    @property
    def time_to_double(self) -> float | None:
        """``ln 2 / sigma``, s, for an unstable mode (``None`` otherwise)."""
        return math.log(2.0) / self.eigenvalue.real if self.eigenvalue.real > 0 else None

    @property
    def time_to_half(self) -> float | None:
        """``ln 2 / -sigma``, s, for a stable mode (``None`` otherwise)."""
        return math.log(2.0) / -self.eigenvalue.real if self.eigenvalue.real < 0 else None

    def describe(self) -> str:
        """One line: eigenvalue, name, dominant states, frequency, damping, time to double or half."""
        lam = self.eigenvalue
        root = f"{lam.real:+.4g} +- {lam.imag:.4g}j" if self.oscillatory else f"{lam.real:+.4g}"
        time = (f"doubles in {self.time_to_double:.3g} s" if self.time_to_double is not None
                else f"halves in {self.time_to_half:.3g} s" if self.time_to_half is not None else "neutral")
        return (f"{root:>20} 1/s  {self.name:<36} {','.join(self.states):<18} wn {self.natural_frequency:8.4g} rad/s"
                f"  zeta {self.damping:+.3f}  {time}")

    def to_json(self) -> dict[str, object]:
        """JSON-ready values (units: 1/s, rad/s, s)."""
        return {
            "eigenvalue": [float(self.eigenvalue.real), float(self.eigenvalue.imag)],
            "name": self.name,
            "states": list(self.states),
            "participation": {n: float(p) for n, p in zip(STATE_NAMES, self.participation)},
            "oscillatory": self.oscillatory,
            "natural_frequency_rad_s": self.natural_frequency,
            "damping": self.damping,
            "time_to_double_s": self.time_to_double,
            "time_to_half_s": self.time_to_half,
        }


def modes(theta: Float[np.ndarray, "40"], g: float = G_SI) -> tuple[Mode, ...]:
    """The modes of the hover model ``theta[40]`` (gravity ``g`` in its units), least stable first."""
    A = np.asarray(build_ab(np.asarray(theta, dtype=np.float64), g)[0])
    return modes_of(A)


def modes_of(A: Float[np.ndarray, "13 13"]) -> tuple[Mode, ...]:
    """The modes of a 13-state matrix ``A`` (1/s), least stable first."""
    values, left, right = scipy.linalg.eig(A, left=True, right=True)
    share = np.abs(left.conj() * right)  # column i: participation in mode i (scaled per column)
    share = share / share.sum(axis=0, keepdims=True)
    shape = np.abs(right) / np.abs(right).max(axis=0, keepdims=True)
    found = [Mode(complex(values[i]), _name(share[:, i]), share[:, i], shape[:, i]) for i in range(values.size)
             if values[i].imag >= 0]  # LAPACK returns a real root with imaginary part exactly 0
    return tuple(sorted(found, key=lambda m: (-m.eigenvalue.real, m.eigenvalue.imag)))


def fastest_doubling(found: tuple[Mode, ...], seen_in: tuple[str, ...] | None = None) -> Mode | None:
    """The unstable mode that doubles fastest, of those that show in the states ``seen_in`` when given (``None``
    for a stable model)."""
    unstable = [m for m in found if m.time_to_double is not None and (seen_in is None or m.seen_in(seen_in))]
    return min(unstable, key=lambda m: m.time_to_double) if unstable else None


def _name(share: Float[np.ndarray, "13"]) -> str:
    """The group holding the largest share, refined by axis (or heave / yaw)."""
    part = dict(zip(STATE_NAMES, share))
    group = max(GROUPS, key=lambda g: sum(part[s] for s in GROUPS[g]))
    total = sum(part[s] for s in GROUPS[group])
    if group == "yaw-heave":
        heave = part["w"] / total
        return group + (" (heave)" if heave > 2 / 3 else " (yaw)" if heave < 1 / 3 else "")
    for axis, states in AXES.items():
        if sum(part[s] for s in GROUPS[group] if s in states) > 2 / 3 * total:
            return f"{group} ({axis})"
    return f"{group} (coupled)"
