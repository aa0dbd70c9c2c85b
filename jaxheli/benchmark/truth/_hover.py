"""Mettler's hover model rebuilt in numpy from ``DESIGN.md`` section 1, apart from :mod:`jaxheli.model`'s code.

States ``u v p q phi theta a b w r r_fb c d`` (m/s, rad/s, rad, flapping rad, yaw feedback, stabiliser rad), sticks
``lat lon ped col``. Only the parameter names come from the library, to read a 40-vector by name.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ...model import PARAM_NAMES

STATES: tuple[str, ...] = ("u", "v", "p", "q", "phi", "theta", "a", "b", "w", "r", "r_fb", "c", "d")
STICKS: tuple[str, ...] = ("lat", "lon", "ped", "col")
GRAVITY = 9.81
"""m/s^2."""

_S = {name: i for i, name in enumerate(STATES)}
_K = {name: i for i, name in enumerate(STICKS)}


def hover_model(theta: np.ndarray, g: float = GRAVITY) -> tuple[np.ndarray, np.ndarray]:
    """Continuous ``A`` (13x13, 1/s) and ``B`` (13x4) of the 40 parameters ``theta`` (``PARAM_NAMES`` order), the
    rotor rows scaled by ``1/tf`` and ``1/ts`` as Mettler and the authors' code have them."""
    p = dict(zip(PARAM_NAMES, np.asarray(theta, dtype=np.float64)))
    A = np.zeros((len(STATES), len(STATES)))
    B = np.zeros((len(STATES), len(STICKS)))

    def row(state: str, **terms: float) -> None:
        for name, value in terms.items():
            if name in _S:
                A[_S[state], _S[name]] += value
            else:
                B[_S[state], _K[name]] += value

    tf, ts = p["tf"], p["ts"]
    row("u", u=p["Xu"], theta=-g, a=p["Xa"])
    row("v", v=p["Yv"], phi=g, b=p["Yb"], ped=p["Yped"])
    row("p", u=p["Lu"], v=p["Lv"], b=p["Lb"], w=p["Lw"])
    row("q", u=p["Mu"], v=p["Mv"], a=p["Ma"], w=p["Mw"], col=p["Mcol"])
    row("phi", p=1.0)
    row("theta", q=1.0)
    row("a", q=-1.0, a=-1.0 / tf, b=p["Ab"] / tf, c=p["Ac"] / tf, lat=p["Alat"] / tf, lon=p["Alon"] / tf)
    row("b", p=-1.0, a=p["Ba"] / tf, b=-1.0 / tf, d=p["Bd"] / tf, lat=p["Blat"] / tf, lon=p["Blon"] / tf)
    row("w", a=p["Za"], b=p["Zb"], w=p["Zw"], r=p["Zr"], col=p["Zcol"])
    row("r", v=p["Nv"], p=p["Np"], w=p["Nw"], r=p["Nr"], r_fb=p["Nrfb"], ped=p["Nped"], col=p["Ncol"])
    row("r_fb", r=p["Kr"], r_fb=p["Krfb"])
    row("c", q=-1.0, c=-1.0 / ts, lon=p["Clon"] / ts)
    row("d", p=-1.0, d=-1.0 / ts, lat=p["Dlat"] / ts)
    return A, B


def gust_matrix(A: np.ndarray) -> np.ndarray:
    """``E`` (13x5) of air-mass motion ``[u_g v_g w_g p_g q_g]``: the aerodynamics see body minus air velocity, so
    the speed columns of ``A`` act on ``-gust``; the rotor and the yaw row see the rate gusts (an air-mass rate is
    a gradient of inflow across the disc), the kinematic rows ``phi' = p``, ``theta' = q`` do not."""
    E = np.zeros((len(STATES), 5))
    for j, name in enumerate(("u", "v", "w")):
        E[:, j] = -A[:, _S[name]]
    aero = [_S[s] for s in ("a", "b", "c", "d", "r")]
    for j, name in enumerate(("p", "q")):
        E[aero, 3 + j] = -A[aero, _S[name]]
    return E


def zoh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation at step ``h`` (s) of ``x' = A x + B v`` for ``v`` held over the step: ``(Ad, Bd)``
    from one matrix exponential of ``[[A, B], [0, 0]] h``."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = scipy.linalg.expm(M * h)
    return E[:n, :n], E[:n, n:]


def state_index(name: str) -> int:
    """Index of state ``name`` in :data:`STATES`."""
    return _S[name]
