"""build_ab against a hand-written matrix and the known eigenstructure of the reference models."""

import numpy as np
import pytest

from jaxheli.model import (
    FOOT, LOWER, N_PARAMS, PARAM_NAMES, PINNED, R50_G, R50_HOVER, R50_SI, STATE_NAMES, TABLE2, UPPER, WIDE_LOWER,
    WIDE_UPPER, build_ab, output_matrix, params_array, params_dict,
)


def _hand_written_table2(g):
    """DESIGN.md's equations typed out with the paper's Table 2 numbers (no use of build_ab's code)."""
    Xu, Xa, Yv, Yb, Lu, Lv, Lb = -0.32066, 40.21598, -0.93658, -16.1151, -0.00121, -0.47665, 133.6111
    Mu, Mv, Ma, tf, Ab, Ac, Ba, Bd = 0.1, -0.09822, 104.9063, 0.093851, -0.19213, 0.061597, 0.083523, 0.984168
    Za, Zb, Zw, Zr, Nv, Np, Nr, Nrfb = 8.166105, 1.028478, 0.045724, -1.39101, 0.009652, -8.23373, -8.69927, 42.69381
    Kr, Krfb, ts = 2.350899, -14.5913, 0.134939
    Alat, Alon, Blat, Blon, Zcol, Nped, Ncol = -0.09993, 0.701979, -0.07779, -0.09942, -6.05944, -27.4672, -3.22316
    Clon, Dlat = -0.09815, 0.793573
    #           u    v    p    q  phi theta   a        b     w    r   rfb    c        d
    A = np.array([
        [Xu,  0,   0,   0,  0,  -g,     Xa,      0,       0,   0,   0,    0,       0],
        [0,   Yv,  0,   0,  g,   0,     0,       Yb,      0,   0,   0,    0,       0],
        [Lu,  Lv,  0,   0,  0,   0,     0,       Lb,      0,   0,   0,    0,       0],
        [Mu,  Mv,  0,   0,  0,   0,     Ma,      0,       0,   0,   0,    0,       0],
        [0,   0,   1,   0,  0,   0,     0,       0,       0,   0,   0,    0,       0],
        [0,   0,   0,   1,  0,   0,     0,       0,       0,   0,   0,    0,       0],
        [0,   0,   0,  -1,  0,   0,  -1/tf,   Ab/tf,      0,   0,   0,  Ac/tf,     0],
        [0,   0,  -1,   0,  0,   0,  Ba/tf,   -1/tf,      0,   0,   0,    0,   Bd/tf],
        [0,   0,   0,   0,  0,   0,     Za,      Zb,     Zw,  Zr,   0,    0,       0],
        [0,   Nv,  Np,  0,  0,   0,     0,       0,       0,  Nr, Nrfb,   0,       0],
        [0,   0,   0,   0,  0,   0,     0,       0,       0,  Kr, Krfb,   0,       0],
        [0,   0,   0,  -1,  0,   0,     0,       0,       0,   0,   0, -1/ts,      0],
        [0,   0,  -1,   0,  0,   0,     0,       0,       0,   0,   0,    0,   -1/ts],
    ])
    B = np.zeros((13, 4))
    B[6] = [Alat / tf, Alon / tf, 0, 0]
    B[7] = [Blat / tf, Blon / tf, 0, 0]
    B[8, 3] = Zcol
    B[9] = [0, 0, Nped, Ncol]
    B[11, 1] = Clon / ts
    B[12, 0] = Dlat / ts
    return A, B


@pytest.mark.parametrize("g", [9.81, 9.8])
def test_build_ab_equals_hand_written_table2(g):
    A_ref, B_ref = _hand_written_table2(g)
    A, B = build_ab(TABLE2, g=g)
    np.testing.assert_allclose(np.asarray(A), A_ref, rtol=1e-14, atol=0)
    np.testing.assert_allclose(np.asarray(B), B_ref, rtol=1e-14, atol=0)


def test_pinned_terms_enter_where_design_says():
    theta = TABLE2.copy()
    values = {"Lw": 1.5, "Mw": 2.5, "Nw": 3.5, "Yped": 4.5, "Mcol": 5.5}
    theta = params_array(values, base=theta)
    A, B = (np.asarray(m) for m in build_ab(theta))
    assert A[2, 8] == 1.5 and A[3, 8] == 2.5 and A[9, 8] == 3.5
    assert B[1, 2] == 4.5 and B[3, 3] == 5.5


def test_batched_build_ab_matches_rows():
    rng = np.random.default_rng(1)
    thetas = LOWER + (UPPER - LOWER) * rng.uniform(size=(3, 5, N_PARAMS))
    A, B = build_ab(thetas)
    assert A.shape == (3, 5, 13, 13) and B.shape == (3, 5, 13, 4)
    for i in range(3):
        for j in range(5):
            Aij, Bij = build_ab(thetas[i, j])
            np.testing.assert_array_equal(np.asarray(A[i, j]), np.asarray(Aij))
            np.testing.assert_array_equal(np.asarray(B[i, j]), np.asarray(Bij))


def test_reference_models_are_open_loop_unstable():
    ev = np.linalg.eigvals(np.asarray(build_ab(TABLE2)[0]))
    assert np.isclose(ev.real.max(), 0.045724, atol=1e-6)
    ev = np.linalg.eigvals(np.asarray(build_ab(R50_HOVER, g=R50_G)[0]))
    top = ev[np.argmax(ev.real)]
    assert abs(top.real - 0.31) < 0.01 and abs(abs(top.imag) - 0.09) < 0.01


def test_bounds_and_names():
    assert len(PARAM_NAMES) == 40 and len(set(PARAM_NAMES)) == 40
    assert (LOWER <= UPPER).all()
    assert PINNED == ("Lw", "Mw", "Nw", "Yped", "Mcol")
    assert params_dict(TABLE2)["Lb"] == 133.6111
    np.testing.assert_array_equal(params_array(params_dict(TABLE2)), TABLE2)


def test_bad_shapes_and_names_raise():
    with pytest.raises(ValueError, match="last axis 40"):
        build_ab(np.zeros(39))
    with pytest.raises(ValueError, match="unknown output channel"):
        output_matrix(("p", "altitude"))
    with pytest.raises(ValueError, match="unknown parameter names"):
        params_array({"Xq": 1.0}, base=TABLE2)


def test_r50_in_si_is_the_feet_model_under_a_velocity_scaling():
    """``A_si = T A_ft T^-1``, ``B_si = T B_ft`` with ``T`` scaling u, v, w by 0.3048 (g in ft/s^2 scaled alike)."""
    a_ft, b_ft = (np.asarray(m) for m in build_ab(R50_HOVER, R50_G))
    a_si, b_si = (np.asarray(m) for m in build_ab(R50_SI, R50_G * FOOT))
    T = np.diag([FOOT if n in ("u", "v", "w") else 1.0 for n in STATE_NAMES])
    np.testing.assert_allclose(a_si, T @ a_ft @ np.linalg.inv(T), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(b_si, T @ b_ft, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(a_si)), np.sort_complex(np.linalg.eigvals(a_ft)),
                               rtol=1e-9, atol=1e-9)


def test_the_wide_box_holds_the_authors_box_both_classes_and_frees_every_pinned_term():
    """The physical ranges contain the authors' box and half to twice every Table 2 and R-50 parameter, and free
    the hover terms the authors' box pins (R-50's Nw = 2.8 among them)."""
    assert np.all(WIDE_LOWER <= LOWER) and np.all(WIDE_UPPER >= UPPER)
    for model in (TABLE2, R50_SI):
        assert np.all(WIDE_LOWER <= np.minimum(0.5 * model, 2 * model))
        assert np.all(np.maximum(0.5 * model, 2 * model) <= WIDE_UPPER)
    pinned = [PARAM_NAMES.index(n) for n in PINNED]
    assert np.all(WIDE_LOWER[pinned] < 0) and np.all(WIDE_UPPER[pinned] > 0)
