"""Forces the linear hover model lacks: quadratic drag against a steady wind, and rotor-speed droop under a governor.

Each returns an extra acceleration on the 13 states, held over one internal step. The catalogue's drag acts on the
body velocity alone (no wind), its rotor coupling is a lagged collective-to-yaw term; here the drag sees the air
and the rotor speed is a state that scales thrust and yaw authority.
"""

from __future__ import annotations

import dataclasses

import numpy as np

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
    """Rotor-speed droop: the fractional speed change ``n = dOmega / Omega`` follows a first-order governor of time
    constant ``tau`` (s), ``n' = -(n + droop col) / tau`` (``droop`` fraction per stick of collective load). Thrust
    scales as ``(1 + n)^2`` (``w' += -2 g n`` about hover, and the collective and pedal derivatives), and the tail
    rotor's yaw authority with it against the engine torque the governor holds: ``r' += yaw n`` (rad/s^2)."""

    droop: float
    tau: float
    yaw: float

    def steady(self, collective: float) -> float:
        """Steady droop ``n`` at a held ``collective`` (stick)."""
        return -self.droop * collective

    def advance(self, n: float, collective: float, h: float) -> float:
        """Exact step ``h`` (s) of the speed for ``collective`` held."""
        decay = np.exp(-h / self.tau)
        return decay * n + (1.0 - decay) * self.steady(collective)

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
