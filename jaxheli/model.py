"""Mettler's 13-state hover model: parameter names, bounds, reference sets and (A, B).

States ``x = [u v p q phi theta a b w r r_fb c d]`` (m/s, rad/s, rad, flapping rad, yaw-rate feedback,
stabiliser states); inputs ``[d_lat d_lon d_ped d_col]`` (normalised sticks). The rotor rows carry the
1/tau_f and 1/tau_s scaling of the authors' code and of Mettler (see ``DESIGN.md``), not the paper's
printed Eq. 4.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ._types import Array, Float, InputMatrix, Params, StateMatrix

G_SI = 9.81
"""Standard gravity used by default, m/s^2."""

STATE_NAMES: tuple[str, ...] = (
    "u", "v", "p", "q", "phi", "theta", "a", "b", "w", "r", "r_fb", "c", "d",
)
INPUT_NAMES: tuple[str, ...] = ("lat", "lon", "ped", "col")
STATE_UNITS: dict[str, str] = {
    "u": "m/s", "v": "m/s", "w": "m/s",
    "p": "rad/s", "q": "rad/s", "r": "rad/s",
    "phi": "rad", "theta": "rad", "a": "rad", "b": "rad",
    "r_fb": "-", "c": "rad", "d": "rad",
}
MEASURABLE: tuple[str, ...] = ("u", "v", "p", "q", "phi", "theta", "a", "b", "w", "r")
"""States a flight log can carry as outputs (CSV column names, ``FlightData.output_names``)."""

FLAPPING: tuple[str, ...] = ("a", "b")
"""Flapping states: the authors' files carry stick multiples under these names, never measurements, so they are
not fitted by default and never restart a simulation."""

PARAM_NAMES: tuple[str, ...] = (
    "Xu", "Xa", "Yv", "Yb", "Lu", "Lv", "Lb", "Lw", "Mu", "Mv",
    "Ma", "Mw", "tf", "Ab", "Ac", "Ba", "Bd", "Za", "Zb", "Zw",
    "Zr", "Nv", "Np", "Nw", "Nr", "Nrfb", "Kr", "Krfb", "ts", "Yped",
    "Mcol", "Alat", "Alon", "Blat", "Blon", "Zcol", "Nped", "Ncol", "Clon", "Dlat",
)
N_PARAMS = len(PARAM_NAMES)
N_STATES = len(STATE_NAMES)
N_INPUTS = len(INPUT_NAMES)
_IDX = {name: i for i, name in enumerate(PARAM_NAMES)}

LOWER = np.array([
    -1, -60, -1, -60, -1, -1, 120, 0, -0.1, -0.1, 40, 0, 0.01, -1, 0, -1, -1, -20, -160, -1,
    -2, 0, -10, 0, -10, -100, -5, -20, 0.01, 0, 0, -0.1, -1, -1, -0.1, -100, -80, -10, -1, -1,
], dtype=np.float64)
"""The authors' lower search bounds (``config_iwo.m``), in :data:`PARAM_NAMES` order."""

UPPER = np.array([
    1, 60, 1, 60, 0, 1, 220, 0, 0.1, 0.1, 120, 0, 1, 0, 1, 1, 1, 20, 100, 1,
    2, 0.01, 10, 0, 10, 100, 5, 20, 1, 0, 0, 0.1, 1, 1, 0.1, 100, 80, 10, 1, 1,
], dtype=np.float64)
"""The authors' upper search bounds, in :data:`PARAM_NAMES` order."""

PINNED: tuple[str, ...] = tuple(n for n, lo, hi in zip(PARAM_NAMES, LOWER, UPPER) if lo == hi)
"""Parameters the bounds pin to zero (hover terms that vanish): Lw, Mw, Nw, Yped, Mcol."""

WIDE_LOWER = np.array([
    -3, -100, -3, -100, -2, -2, 10, -2, -2, -2, 10, -2, 0.01, -2, -2, -2, -2, -50, -300, -3,
    -5, -3, -30, -10, -30, -300, -10, -60, 0.01, -10, -10, -2, -2, -2, -2, -300, -300, -30, -2, -2,
], dtype=np.float64)
"""Lower bounds of the physical ranges of small unmanned helicopters (about 1-100 kg, hingeless or teetering
rotor, with or without a stabilizer bar), in :data:`PARAM_NAMES` order: speed dampings and stabilities up to a
few 1/s, flapping springs ``Lb, Ma`` 10-2000 1/s^2, time constants 10 ms to 1 s, the authors' pinned hover terms
(``Lw, Mw, Nw, Yped, Mcol``) freed, every coupling of either sign. The box a diagnosis widens the base model's
to before it credits an unmodelled effect, and ``--box wide``."""

WIDE_UPPER = np.array([
    1, 100, 1, 100, 2, 2, 2000, 2, 2, 2, 2000, 2, 1, 2, 2, 2, 2, 50, 300, 1,
    5, 3, 30, 10, 30, 300, 10, 60, 1, 10, 10, 2, 2, 2, 2, 300, 300, 30, 2, 2,
], dtype=np.float64)
"""Upper bounds of the physical ranges (:data:`WIDE_LOWER`)."""

TABLE2 = np.array([
    -0.32066, 40.21598, -0.93658, -16.1151, -0.00121, -0.47665, 133.6111, 0.0, 0.1, -0.09822,
    104.9063, 0.0, 0.093851, -0.19213, 0.061597, 0.083523, 0.984168, 8.166105, 1.028478, 0.045724,
    -1.39101, 0.009652, -8.23373, 0.0, -8.69927, 42.69381, 2.350899, -14.5913, 0.134939, 0.0,
    0.0, -0.09993, 0.701979, -0.07779, -0.09942, -6.05944, -27.4672, -3.22316, -0.09815, 0.793573,
], dtype=np.float64)
"""The paper's Table 2 IWO parameters (TREX 550, SI units)."""

R50_HOVER = np.array([
    -0.0505, -32.2, -0.1539, 32.2, -0.1437, 0.1432, 166.1, 0.0, -0.0561, -0.0585,
    82.57, 0.0, 0.0463, -0.1892, 0.6439, 0.3681, 0.7103, -9.748, -131.2, -0.6141,
    0.9303, 0.3031, -3.525, 0.8568, -4.129, -33.07, 2.163, -8.258, 0.3415, 0.0,
    0.0, 0.0313, -0.1004, 0.1398, 0.0138, -45.84, 33.07, -3.329, -0.2587, 0.2731,
], dtype=np.float64)
"""Mettler's Yamaha R-50 hover model (feet-based units: use with ``g = R50_G``)."""

R50_G = 32.2
"""Gravity in ft/s^2, the unit system of :data:`R50_HOVER`."""

FOOT = 0.3048
"""Metres per foot."""

_LENGTH_POWER = {"Xa": 1, "Yb": 1, "Za": 1, "Zb": 1, "Zr": 1, "Yped": 1, "Zcol": 1,
                 "Lu": -1, "Lv": -1, "Lw": -1, "Mu": -1, "Mv": -1, "Mw": -1, "Nv": -1, "Nw": -1}
"""Power of length in each parameter's unit (speed derivatives of angular rates per unit speed, -1; speed
derivatives per angle, rate or stick, +1); the others carry none."""


def feet_to_si(theta: Float[np.ndarray, "40"]) -> Float[np.ndarray, "40"]:
    """A feet-based parameter set (velocities in ft/s) in SI units (m/s): each parameter times
    ``FOOT ** power`` (:data:`_LENGTH_POWER`). The model in SI is the feet model seen through the state
    scaling ``u, v, w -> FOOT u, FOOT v, FOOT w`` (with ``g`` scaled alike)."""
    scale = np.array([FOOT ** _LENGTH_POWER.get(n, 0) for n in PARAM_NAMES])
    return np.asarray(theta, dtype=np.float64) * scale


R50_SI = feet_to_si(R50_HOVER)
"""Mettler's Yamaha R-50 hover model in SI units (m/s; use with the default ``g``). Outside the authors' TREX
box in ``Mu``, ``Nv`` and ``Nw`` (a larger, heavier helicopter)."""


def params_dict(theta: Float[np.ndarray, "40"]) -> dict[str, float]:
    """Name one parameter vector: ``{name: value}`` in :data:`PARAM_NAMES` order."""
    theta = np.asarray(theta, dtype=np.float64)
    if theta.shape != (N_PARAMS,):
        raise ValueError(f"params_dict: expected shape (40,), got {theta.shape}")
    return {n: float(v) for n, v in zip(PARAM_NAMES, theta)}


def params_array(values: dict[str, float], base: Float[np.ndarray, "40"] | None = None) -> np.ndarray:
    """Inverse of :func:`params_dict`; names missing from ``values`` come from ``base`` (required then)."""
    unknown = sorted(set(values) - set(PARAM_NAMES))
    if unknown:
        raise ValueError(f"params_array: unknown parameter names {unknown}")
    if base is None:
        missing = [n for n in PARAM_NAMES if n not in values]
        if missing:
            raise ValueError(f"params_array: missing parameters {missing} and no base given")
        out = np.zeros(N_PARAMS)
    else:
        out = np.array(base, dtype=np.float64)
    for name, value in values.items():
        out[_IDX[name]] = float(value)
    return out


def build_ab(theta: Params, g: float = G_SI) -> tuple[StateMatrix, InputMatrix]:
    """Continuous-time ``A`` (13x13, 1/s) and ``B`` (13x4) of the hover model.

    Works on one vector ``theta[40]`` or any batch ``theta[..., 40]`` (jit/vmap/grad friendly).
    ``g`` is gravity in the unit system of the parameters (9.81 m/s^2 by default).
    """
    theta = jnp.asarray(theta)
    if theta.shape[-1:] != (N_PARAMS,):
        raise ValueError(f"build_ab: theta must have last axis 40, got shape {theta.shape}")
    P = {name: theta[..., i] for i, name in enumerate(PARAM_NAMES)}
    inv_tf = 1.0 / P["tf"]
    inv_ts = 1.0 / P["ts"]
    one = jnp.ones_like(P["tf"])
    S = {name: i for i, name in enumerate(STATE_NAMES)}
    U = {name: i for i, name in enumerate(INPUT_NAMES)}
    a_entries = [
        ("u", "u", P["Xu"]), ("u", "theta", -g * one), ("u", "a", P["Xa"]),
        ("v", "v", P["Yv"]), ("v", "phi", g * one), ("v", "b", P["Yb"]),
        ("p", "u", P["Lu"]), ("p", "v", P["Lv"]), ("p", "b", P["Lb"]), ("p", "w", P["Lw"]),
        ("q", "u", P["Mu"]), ("q", "v", P["Mv"]), ("q", "a", P["Ma"]), ("q", "w", P["Mw"]),
        ("phi", "p", one), ("theta", "q", one),
        ("a", "q", -one), ("a", "a", -inv_tf), ("a", "b", P["Ab"] * inv_tf), ("a", "c", P["Ac"] * inv_tf),
        ("b", "p", -one), ("b", "a", P["Ba"] * inv_tf), ("b", "b", -inv_tf), ("b", "d", P["Bd"] * inv_tf),
        ("w", "a", P["Za"]), ("w", "b", P["Zb"]), ("w", "w", P["Zw"]), ("w", "r", P["Zr"]),
        ("r", "v", P["Nv"]), ("r", "p", P["Np"]), ("r", "w", P["Nw"]), ("r", "r", P["Nr"]),
        ("r", "r_fb", P["Nrfb"]),
        ("r_fb", "r", P["Kr"]), ("r_fb", "r_fb", P["Krfb"]),
        ("c", "q", -one), ("c", "c", -inv_ts),
        ("d", "p", -one), ("d", "d", -inv_ts),
    ]
    b_entries = [
        ("v", "ped", P["Yped"]), ("q", "col", P["Mcol"]),
        ("a", "lat", P["Alat"] * inv_tf), ("a", "lon", P["Alon"] * inv_tf),
        ("b", "lat", P["Blat"] * inv_tf), ("b", "lon", P["Blon"] * inv_tf),
        ("w", "col", P["Zcol"]),
        ("r", "ped", P["Nped"]), ("r", "col", P["Ncol"]),
        ("c", "lon", P["Clon"] * inv_ts), ("d", "lat", P["Dlat"] * inv_ts),
    ]
    A = _scatter(theta, a_entries, S, S, (N_STATES, N_STATES))
    B = _scatter(theta, b_entries, S, U, (N_STATES, N_INPUTS))
    return A, B


def _scatter(theta, entries, rows, cols, shape) -> Array:
    """Place ``(row, col, value)`` entries into a zero matrix with one batched scatter."""
    r = np.array([rows[e[0]] for e in entries])
    c = np.array([cols[e[1]] for e in entries])
    values = jnp.stack([jnp.broadcast_to(e[2], theta.shape[:-1]) for e in entries], axis=-1)
    out = jnp.zeros(theta.shape[:-1] + shape, dtype=values.dtype)
    return out.at[..., r, c].set(values)


def output_indices(names: tuple[str, ...] | list[str]) -> np.ndarray:
    """State indices of measured output channels (e.g. ``("p", "q", "phi", "theta")``)."""
    bad = [n for n in names if n not in MEASURABLE]
    if bad:
        raise ValueError(f"unknown output channel(s) {bad}; measurable states are {MEASURABLE}")
    return np.array([STATE_NAMES.index(n) for n in names], dtype=np.int32)


def output_matrix(names: tuple[str, ...] | list[str]) -> Float[Array, "channel 13"]:
    """Selection matrix ``C`` mapping the 13 states to the named measured outputs."""
    idx = output_indices(names)
    return jnp.asarray(np.eye(N_STATES)[idx])
