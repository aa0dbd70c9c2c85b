"""Frequency-domain identification (CIFER) against independent references: the model response against a numpy
resolvent of scipy's ZOH discretisation, the Welch estimate against scipy.signal.csd, Tischler's J against a
hand computation, and recovery of a known model by ``identify(method="freq+polish")`` and the CLI."""

import json

import numpy as np
import pytest
import scipy.linalg
import scipy.signal as ss

from jaxheli.cli import main
from jaxheli.identify import identify, validation_block
from jaxheli.io import save_npz
from jaxheli.model import LOWER, TABLE2, UPPER, build_ab, output_matrix
from jaxheli.optim.frequency_fit import frequency_target
from jaxheli.problem import make_problem
from jaxheli.spectra import cifer_cost, estimate_frequency_response
from jaxheli.synth.excitation import Excitation
from jaxheli.synth.piloted import piloted_flight

DT = 0.02
CHANNELS = ("u", "v", "p", "q", "phi", "theta", "w", "r")
ENGINE = {"starts": 1, "screen": 1, "max_steps": 100}
"""Frequency-fit settings of the recovery and CLI runs (the CLI reuses the compiled solve)."""


@pytest.fixture(scope="module")
def flights():
    train = piloted_flight(duration=40.0, dt=DT, seed=1)  # 3-2-1-1s then sweeps on every axis
    validate = piloted_flight(duration=20.0, dt=DT, excitation=Excitation("3211", unit=0.3), seed=2)
    return train, validate


def _zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """ZOH discretisation by the exponential of the augmented matrix (scipy)."""
    n, m = B.shape
    M = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * dt)
    return M[:n, :n], M[:n, n:]


def test_fitted_model_response_matches_numpy_resolvent(flights):
    train, _ = flights
    theta = TABLE2 * (1.0 + 0.2 * np.random.default_rng(0).uniform(-1, 1, 40))
    A, B = (np.asarray(M) for M in build_ab(theta))
    C = np.asarray(output_matrix(CHANNELS))
    for hold in ("zoh", "foh"):
        target = frequency_target(make_problem(train, outputs=CHANNELS, hold=hold))
        f = np.asarray(target.freq)
        if hold == "zoh":
            Ad, Bd = _zoh(A, B, DT)
            ref = np.stack([C @ np.linalg.solve(np.exp(2j * np.pi * fk * DT) * np.eye(13) - Ad, Bd) for fk in f])
        else:  # FOH runs are compared with the continuous response
            ref = np.stack([C @ np.linalg.solve(2j * np.pi * fk * np.eye(13) - A, B) for fk in f])
        np.testing.assert_allclose(np.asarray(target.model(theta)), ref, rtol=1e-8, atol=1e-12 * np.abs(ref).max())


def test_single_input_estimate_matches_scipy_csd():
    rng = np.random.default_rng(4)
    n, dt, nperseg = 8000, 0.01, 500
    u = rng.normal(size=n)
    _, y = ss.dlsim(ss.dlti([0.2, 0.1], [1.0, -1.2, 0.5], dt=dt), u)
    y = y[:, 0] + 0.3 * rng.normal(size=n)
    est = estimate_frequency_response(u[:, None], y[:, None], dt, segment_seconds=nperseg * dt, overlap=0.5)
    options = {"fs": 1 / dt, "window": "hann", "nperseg": nperseg, "noverlap": nperseg // 2}
    f, puu = ss.welch(u, **options)
    _, puy = ss.csd(u, y, **options)  # scipy: E[conj(U) Y], the project's G_yu
    _, coh = ss.coherence(u, y, **options)
    np.testing.assert_allclose(np.asarray(est.freq), f[1:], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(est.response)[:, 0, 0], (puy / puu)[1:], rtol=1e-7)
    np.testing.assert_allclose(np.asarray(est.coherence)[:, 0, 0], coh[1:], rtol=1e-6, atol=1e-9)


def test_cifer_cost_matches_a_hand_computation():
    rng = np.random.default_rng(5)
    shape = (12, 2, 3)
    flight = rng.lognormal(size=shape) * np.exp(1j * rng.uniform(-np.pi, np.pi, shape))
    model = flight * rng.lognormal(0.0, 0.5, shape) * np.exp(1j * rng.uniform(-3.0, 3.0, shape))  # wraps past 180
    coherence = rng.uniform(0.0, 1.0, shape)
    use = coherence >= 0.6
    use[:, 1, 2] = False  # a pair without bins: NaN
    J = np.full((2, 3), np.nan)
    for k, m in np.ndindex(2, 3):
        w = use[:, k, m]
        if not w.any():
            continue
        mag = 20 * np.log10(np.abs(model[w, k, m])) - 20 * np.log10(np.abs(flight[w, k, m]))
        phase = np.degrees(np.angle(model[w, k, m])) - np.degrees(np.angle(flight[w, k, m]))
        phase = (phase + 180.0) % 360.0 - 180.0
        weight = (1.58 * (1 - np.exp(-coherence[w, k, m]))) ** 2
        J[k, m] = 20.0 / w.sum() * np.sum(weight * (mag**2 + 0.01745 * phase**2))
    np.testing.assert_allclose(np.asarray(cifer_cost(model, flight, coherence, use)), J, rtol=1e-10)


@pytest.mark.slow  # ~60 s on two busy cores, mostly compiling (frequency fit, two polish rounds, scores)
def test_freq_polish_recovers_the_truth_from_a_perturbed_start(flights):
    train, validate = flights
    start = np.clip(TABLE2 * (1 + 0.3 * np.random.default_rng(6).uniform(-1, 1, 40)), LOWER, UPPER)
    result = identify(train, method="freq+polish", validate=validate, start=start, seed=0, freq_options=ENGINE,
                      polish_steps=30, polish_rounds=2)
    truth = validation_block(TABLE2, validate, CHANNELS)
    freq = result.frequency
    assert freq["fit"]["j_average"] < 50 and freq["acceptable"], freq  # the frequency fit alone: excellent
    assert freq["j"]["lat->p"] < 100 and freq["j"]["lon->q"] < 100, freq["j"]
    gap = {c: result.validate["fit_percent"][c] - truth["fit_percent"][c] for c in CHANNELS}
    assert all(g > -1.0 for g in gap.values()), gap  # measured: within 0.13 points
    assert result.settings["polish_objective"] == "output-error"
    assert json.dumps(result.to_json())  # J's and metrics are JSON-ready


def test_cli_runs_the_frequency_method(flights, tmp_path, capsys):
    with pytest.raises(SystemExit) as done:
        main(["identify", "--method", "freq", "--help"])
    assert done.value.code == 0 and "--freq-band" in capsys.readouterr().out
    train, _ = flights
    save_npz(train, tmp_path / "train.npz")
    out = tmp_path / "run"
    rc = main(["identify", "--method", "freq", "--train", str(tmp_path / "train.npz"), "--out", str(out),
               "--freq-starts", str(ENGINE["starts"]), "--freq-screen", str(ENGINE["screen"]),
               "--freq-steps", str(ENGINE["max_steps"])])
    assert rc == 0
    content = json.loads((out / "result.json").read_text())
    assert content["method"] == "freq" and content["frequency"]["j_average"] > 0
    assert set(content["frequency"]["j"]) >= {"lat->p", "lon->q"}
    for key in ("pearson", "tic", "rmse", "fit_percent"):
        assert set(content["train"][key]) == set(CHANNELS), key
    assert (out / "frequency_response.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
