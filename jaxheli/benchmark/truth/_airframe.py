"""Forces the linear hover model lacks: quadratic drag against a steady wind, and rotor-speed droop under a governor.

Each returns an extra acceleration on the 13 states, held over one internal step. The catalogue's drag acts on the
body velocity alone (no wind), its rotor coupling is a lagged collective-to-yaw term; here the drag sees the air
and the rotor speed is a state that scales thrust and yaw authority.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from ._hover import GRAVITY, STICKS, state_index

_U, _V, _W, _R = (state_index(s) for s in ("u", "v", "w", "r"))
_PED, _COL = STICKS.index("ped"), STICKS.index("col")


@dataclasses.dataclass(frozen=True)
class Drag:
    """``X_uu |V| u_rel`` and ``Y_vv |V| v_rel`` (1/m) on the velocity relative to a steady wind ``wind`` (m/s, along
    body u and v; ``|V|`` the horizontal airspeed ``sqrt(u_rel^2 + v_rel^2)``: drag along the relative wind, unlike the
    catalogue's per-axis form), less its trim value (the hover in that wind is trimmed)."""

    xuu: float
    yvv: float
    wind: tuple[float, float] = (0.0, 0.0)

    def force(self, u_rel: np.ndarray, v_rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Drag accelerations (m/s^2) at relative velocities ``u_rel``, ``v_rel`` (m/s)."""
        speed = np.hypot(u_rel, v_rel)
        return self.xuu * speed * u_rel, self.yvv * speed * v_rel

    def accel(self, x: np.ndarray, gust: np.ndarray) -> np.ndarray:
        """Extra acceleration on the states at state ``x`` with air-mass motion ``gust`` (``u_g v_g ...``)."""
        wu, wv = self.wind
        fu, fv = self.force(x[_U] - wu - gust[0], x[_V] - wv - gust[1])
        tu, tv = self.force(np.float64(-wu), np.float64(-wv))
        out = np.zeros_like(x)
        out[_U], out[_V] = fu - tu, fv - tv
        return out


@dataclasses.dataclass(frozen=True)
class Governor:
    """Rotor-speed droop under a governor with integral action: the fractional speed change ``n = dOmega / Omega``
    follows ``n' = -(n + droop col) / tau - ki m``, ``m' = n`` (``droop`` fraction per stick of collective load,
    ``tau`` the rotor's time constant in s, ``ki`` the governor's integral gain in 1/s^2), so a collective step
    droops the speed for a moment and the governor restores it (no droop at all in a steady state when ``ki > 0``;
    ``ki = 0`` is a proportional governor, a first-order droop). Thrust scales as ``(1 + n)^2`` (``w' += -2 g n``
    about hover, and the collective and pedal derivatives), and the tail rotor's yaw authority with it against the
    engine torque the governor holds: ``r' += yaw n`` (rad/s^2)."""

    droop: float
    tau: float
    yaw: float
    ki: float = 0.0

    def steady(self, collective: float) -> float:
        """Steady droop ``n`` at a held ``collective`` (stick)."""
        return 0.0 if self.ki > 0 else -self.droop * collective

    def advance(self, state: np.ndarray, collective: float, h: float) -> np.ndarray:
        """Exact step ``h`` (s) of the speed and its integral ``(n, m)`` for ``collective`` held."""
        M = np.array([[-1.0 / self.tau, -self.ki, -self.droop / self.tau], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
        return (scipy.linalg.expm(M * h) @ np.append(state, collective))[:2]

    def accel(self, n: float, servo: np.ndarray, B: np.ndarray) -> np.ndarray:
        """Extra acceleration on the states at speed change ``n`` with servo positions ``servo`` (``B``, the
        model's input matrix, gives the collective and pedal derivatives it scales)."""
        thrust = (1.0 + n) ** 2 - 1.0
        out = np.zeros(B.shape[0])
        for row in (_W, _R):
            out[row] = thrust * (B[row, _COL] * servo[_COL] + B[row, _PED] * servo[_PED])
        out[_W] += -2.0 * GRAVITY * n
        out[_R] += self.yaw * n
        return out
