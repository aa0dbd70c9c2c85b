"""The independent truth simulator (jaxheli/benchmark/truth): its isolation from the code it checks, its hover model
against the library's, each effect against an analytic case, and its detectability verdict."""

import ast
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

from jaxheli.benchmark import truth as ts
from jaxheli.benchmark.independent import independent_trial
from jaxheli.effects import registry as fx
from jaxheli.model import R50_G, R50_HOVER, R50_SI, TABLE2, build_ab
from jaxheli.synth.piloted import DEFAULT_NOISE, DEFAULT_OUTPUTS

PACKAGE = Path(ts.__file__).parent
ALLOWED_FROM_MODEL = {"PARAM_NAMES", "TABLE2", "R50_SI", "R50_HOVER", "LOWER", "UPPER"}


def _imports(path: Path) -> list[tuple[str, tuple[str, ...]]]:
    """``(absolute module, imported names)`` of every import in the module at ``path``."""
    package = "jaxheli.benchmark.truth"
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(alias.name, ()) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level else ""
            module = ".".join(p for p in (base, node.module or "") if p)
            out.append((module, tuple(alias.name for alias in node.names)))
    return out


def test_the_simulator_imports_nothing_from_jaxheli_but_model_constants():
    modules = sorted(PACKAGE.glob("*.py"))
    assert len(modules) >= 8
    for path in modules:
        for module, names in _imports(path):
            if module.startswith("jaxheli.benchmark.truth") or not module.startswith("jaxheli"):
                continue
            assert module == "jaxheli.model", f"{path.name} imports {module}"
            assert set(names) <= ALLOWED_FROM_MODEL, f"{path.name} imports {names} from jaxheli.model"


@pytest.mark.parametrize("theta, g", [(TABLE2, 9.81), (R50_SI, 9.81), (R50_HOVER, R50_G)])
def test_the_hover_model_equals_the_librarys(theta, g):
    A, B = ts.hover_model(theta, g)
    A_lib, B_lib = (np.asarray(m) for m in build_ab(theta, g))
    np.testing.assert_allclose(A, A_lib, rtol=0, atol=1e-12)
    np.testing.assert_allclose(B, B_lib, rtol=0, atol=1e-12)


def test_a_link_delay_shifts_a_step_by_its_latency_between_frames():
    dt = 0.01
    servo = ts.ServoState(ts.Servo(delay=(0.0, 2 * dt, 0.025, 3 * dt)), h=dt / 10)
    commands = np.zeros((12, 4))
    commands[5:] = 0.3
    for k, c in enumerate(commands):
        servo.frame(c, k * dt)
    reaching = np.array([servo.reaching(t) for t in dt / 10 * np.arange(120)])
    t = dt / 10 * np.arange(120)
    for axis, delay in enumerate((0.0, 2 * dt, 0.025, 3 * dt)):
        np.testing.assert_array_equal(reaching[:, axis], 0.3 * (t >= 5 * dt + delay - 1e-9))


def test_a_jittery_lossy_link_holds_the_last_frame_and_never_reorders():
    dt = 0.02
    servo = ts.ServoState(ts.Servo(delay=(0.03,) * 4, jitter=0.5 * dt, drop=0.2), h=dt / 10,
                          rng=np.random.default_rng(4))
    for k in range(300):
        servo.frame(np.full(4, float(k)), k * dt)
    lag = np.array([k * dt - (servo.reaching(k * dt + 0.5 * dt)[0]) * dt for k in range(2, 300)])
    assert np.all(np.diff([a[0] for a in servo.arrivals]) >= 0)
    assert 0.8 * 300 * 0.8 < len(servo.arrivals) < 300  # about a fifth of the frames lost
    assert lag.min() >= 0.03 - 0.5 * dt - 1e-9 and np.ptp(lag) > 2 * dt  # jitter and losses move the delay


def test_backlash_passes_a_reversal_only_after_the_play_is_taken_up():
    servo = ts.ServoState(ts.Servo(backlash=(0.02, 0.0, 0.0, 0.0)), h=0.01)
    command = np.concatenate([np.linspace(0, 0.1, 11), np.linspace(0.1, 0.05, 6)])
    out = np.array([servo.step(np.array([c, c, 0.0, 0.0])) for c in command])
    np.testing.assert_allclose(out[1:11, 0], command[1:11] - 0.01)  # dragged 0.01 behind going up
    np.testing.assert_allclose(out[11, 0], 0.09)  # the first 0.01 back stays in the play
    np.testing.assert_allclose(out[-1, 0], 0.06)  # then dragged 0.01 ahead going down
    np.testing.assert_allclose(out[:, 1], command)


def test_travel_stops_clip_and_a_rate_limit_ramps_at_its_slope():
    h = 0.001
    servo = ts.ServoState(ts.Servo(limit=(0.2, np.inf, np.inf, np.inf), rate=(np.inf, 2.0, np.inf, np.inf)), h)
    positions = np.array([servo.step(np.array([0.5, 1.0, -0.1, 0.0])) for _ in range(1000)])
    np.testing.assert_allclose(positions[:, 0], 0.2)
    t = h * np.arange(1, 1001)
    np.testing.assert_allclose(positions[:, 1], np.minimum(2.0 * t, 1.0), atol=1e-12)
    np.testing.assert_allclose(positions[:, 2], -0.1)


def test_the_second_order_servo_follows_its_analytic_step_response_with_unit_dc_gain():
    wn, zeta, h = 20.0, 0.6, 0.002
    servo = ts.ServoState(ts.Servo(wn=(wn,) * 4, zeta=(zeta,) * 4), h)
    positions = np.array([servo.step(np.ones(4))[0] for _ in range(1500)])
    t = h * np.arange(1, 1501)
    wd = wn * np.sqrt(1 - zeta**2)
    analytic = 1 - np.exp(-zeta * wn * t) * np.sin(wd * t + np.arccos(zeta)) / np.sqrt(1 - zeta**2)
    np.testing.assert_allclose(positions, analytic, atol=1e-10)
    assert abs(positions[-1] - 1.0) < 1e-6


def test_dryden_turbulence_has_the_standards_variance_and_spectrum():
    dryden = ts.Dryden(w20=4.0, altitude=4.0, speed=3.0, span=1.5)
    h = 0.02
    gusts = dryden.sample(2**18, h, np.random.default_rng(1))
    sigmas = np.array(dryden.sigmas())
    # stationary variance of each discretised filter (white noise of intensity pi): sigma^2 up to the ZOH error
    for j, sigma in enumerate(sigmas):
        a, b, c, d, _ = scipy.signal.cont2discrete(scipy.signal.tf2ss(*dryden.filters()[j]), h, method="zoh")
        P = scipy.linalg.solve_discrete_lyapunov(a, np.pi / h * b @ b.T)
        assert abs(np.sqrt((c @ P @ c.T)[0, 0] + np.pi / h * d[0, 0] ** 2) / sigma - 1) < 0.01
    # sample std within sampling error (the slowest, u, has ~2**18 h / (2 L_u / V) ~ 200 independent stretches)
    np.testing.assert_allclose(gusts[:, :3].std(axis=0), sigmas, rtol=0.15)
    f, psd = scipy.signal.welch(gusts[:, :3], fs=1 / h, nperseg=2**12, axis=0)
    band = (f > 0.05) & (f < 2.0)
    ratio = psd[band] / (2 * np.pi * dryden.psd(2 * np.pi * f[band]))
    np.testing.assert_allclose(np.median(ratio, axis=0), 1.0, atol=0.1)


def test_drag_acts_on_the_velocity_relative_to_the_wind_about_trim():
    drag = ts.Drag(-2.0, -1.5, (0.5, -0.3))
    u = np.linspace(-2, 2, 9)
    fu, fv = drag.force(u, 0.0 * u)
    np.testing.assert_allclose(fu, -2.0 * np.abs(u) * u)
    np.testing.assert_allclose(drag.force(3.0, 4.0), (-2.0 * 5.0 * 3.0, -1.5 * 5.0 * 4.0))  # along the airspeed
    x = np.zeros(13)
    x[0], x[1] = 1.2, -0.4
    accel = drag.accel(x, np.zeros(5))
    air, trim = np.hypot(0.7, -0.1), np.hypot(0.5, 0.3)
    np.testing.assert_allclose(accel[:2], [-2.0 * (air * 0.7 - trim * -0.5), -1.5 * (air * -0.1 - trim * 0.3)])
    assert not np.any(accel[2:]) and not np.any(drag.accel(np.zeros(13), np.zeros(5)))


def test_a_misaligned_gyro_triad_rotates_p_q_and_the_velocity_frame_rotates_u_v():
    eps, eps_v = np.deg2rad(4.0), np.deg2rad(-6.0)
    states = np.random.default_rng(0).standard_normal((50, 13))
    outputs = ("u", "v", "p", "q", "phi", "theta", "w", "r")
    y = ts.read(states, outputs, ts.Imu(yaw=eps, velocity_yaw=eps_v))
    p, q, u, v = (states[:, ts.STATES.index(s)] for s in ("p", "q", "u", "v"))
    np.testing.assert_allclose(y[:, 2], np.cos(eps) * p + np.sin(eps) * q)
    np.testing.assert_allclose(y[:, 3], -np.sin(eps) * p + np.cos(eps) * q)
    angle = np.arctan2(y[:, 3], y[:, 2]) - np.arctan2(q, p)
    np.testing.assert_allclose(np.angle(np.exp(1j * angle)), -eps, atol=1e-12)
    np.testing.assert_allclose(y[:, 0], np.cos(eps_v) * u + np.sin(eps_v) * v)
    np.testing.assert_array_equal(y[:, 4:7], states[:, [4, 5, 8]])
    scaled = ts.read(states, outputs, ts.Imu(scale=(0.05, -0.03, 0.0)))
    np.testing.assert_allclose(scaled[:, 2:4], np.stack([1.05 * p, 0.97 * q], axis=1))
    tilted = ts.Imu(tilt=(0.0, 0.02)).gyro_matrix()
    assert tilted[0, 2] == pytest.approx(-np.sin(0.02))  # a pitched triad reads r on its p axis
    mounted = ts.read(states, outputs, ts.Imu(velocity_tilt=(0.0, 0.05), velocity_scale=(0.04, -0.02)))
    w = states[:, ts.STATES.index("w")]
    np.testing.assert_allclose(mounted[:, 0], 1.04 * (np.cos(0.05) * u - np.sin(0.05) * w))  # w read on u
    np.testing.assert_allclose(mounted[:, 1], 0.98 * v)


def test_a_bias_drift_settles_and_wanders_as_a_gauss_markov_process():
    drift = ts.BiasDrift("q", start=0.03, settle=-0.02, settle_tau=10.0, sigma=0.01, tau=2.0)
    time = np.arange(0.0, 20.0, 0.05)
    rng = np.random.default_rng(3)
    paths = np.array([drift.sample(time, rng) for _ in range(4000)])
    mean = 0.03 - 0.02 * (1 - np.exp(-time / 10.0))
    np.testing.assert_allclose(paths.mean(axis=0), mean, atol=4 * 0.01 / np.sqrt(4000))
    np.testing.assert_allclose(paths.std(axis=0), 0.01, rtol=0.06)
    wander = paths - mean
    lag = 40  # 2 s, one correlation time
    rho = np.mean(wander[:, :-lag] * wander[:, lag:]) / 0.01**2
    assert rho == pytest.approx(np.exp(-1.0), abs=0.03)  # a walk's correlation would not decay


def test_governor_droop_settles_on_its_analytic_gain_and_integral_action_restores_the_speed():
    governor = ts.Governor(droop=0.06, tau=0.5, yaw=50.0)
    state, h = np.zeros(2), 0.01
    history = []
    for _ in range(3000):
        state = governor.advance(state, 0.4, h)
        history.append(state[0])
    assert history[-1] == pytest.approx(-0.06 * 0.4, rel=1e-9)
    assert history[49] == pytest.approx(-0.024 * (1 - np.exp(-1.0)), rel=1e-9)  # one time constant
    integral = ts.Governor(droop=0.06, tau=0.5, yaw=50.0, ki=9.0)
    t = h * np.arange(1001)
    out = np.array(scipy.signal.lsim(([-0.12, 0.0], [1.0, 2.0, 9.0]), np.full(1001, 0.4), t)[1])[1:]
    state, path = np.zeros(2), []
    for _ in range(1000):
        state = integral.advance(state, 0.4, h)
        path.append(state[0])
    np.testing.assert_allclose(path, out, atol=1e-6)  # -(droop / tau) s / (s^2 + s / tau + ki)
    assert abs(path[-1]) < 1e-4 and min(path) < -0.005 and integral.steady(0.4) == 0.0
    A, B = ts.hover_model(TABLE2)
    accel = governor.accel(-0.024, np.zeros(4), B)
    r, w = ts.STATES.index("r"), ts.STATES.index("w")
    assert accel[r] == pytest.approx(-1.2) and accel[w] == pytest.approx(2 * 9.81 * 0.024)
    assert np.count_nonzero(accel) == 2


def test_quantisation_rounds_to_whole_steps():
    y = np.random.default_rng(0).normal(0, 0.05, (400, 2))
    out = ts.Quantiser({"q": 0.01}).apply(y, ("p", "q"))
    np.testing.assert_array_equal(out[:, 0], y[:, 0])
    np.testing.assert_allclose(out[:, 1] / 0.01, np.round(out[:, 1] / 0.01), atol=1e-9)
    assert np.max(np.abs(out[:, 1] - y[:, 1])) <= 0.005 + 1e-12
    assert len(np.unique(np.round(out[:, 1], 9))) < 40


def test_a_vibration_line_sits_at_its_frequency_and_aliases_into_the_logger():
    line = ts.Vibration(0.02, 24.0, 0.3)
    for dt, expected in ((0.001, 24.0), (0.05, 4.0)):
        time = dt * np.arange(4000)
        spectrum = np.abs(np.fft.rfft(line.sample(time)))
        peak = np.fft.rfftfreq(len(time), dt)[np.argmax(spectrum)]
        assert peak == pytest.approx(expected, abs=1 / (len(time) * dt))
        assert line.alias(dt) == pytest.approx(expected)


def test_detectability_is_false_without_an_effect_and_true_for_a_large_one():
    sigma = np.array([ts.NOISE[c] for c in ts.OUTPUTS])
    common = dict(style="validate", duration=10.0, dt=0.05, seed=7, noise=sigma)
    for effects, expected in ((ts.Effects(drag=ts.Drag(0.0, 0.0)), False),
                              (ts.Effects(servo=ts.Servo(delay=(0.15,) * 4)), True)):
        flight = ts.fly(TABLE2, effects, **common)
        score = ts.detectability(TABLE2, flight, sigma, seed=7, duration=10.0, dt=0.05)
        assert (score > 1.0) is expected, score
    none = ts.truth_trial("none", 3, TABLE2, style="regulation", duration=10.0)
    assert none.score == 0.0 and not none.detectable


def test_a_servo_stop_that_only_the_validation_flight_reaches_is_detectable_but_not_resolvable():
    trial = ts.truth_trial("servo_limits", 0, TABLE2, style="regulation", duration=10.0)
    train_clean = ts.fly(TABLE2, ts.Effects(), style="regulation", duration=10.0, dt=0.05, seed=0,
                         noise=trial.noise)
    assert trial.train_score == pytest.approx(
        ts.detectability_ratio(trial.train.clean, train_clean.clean, trial.noise))
    assert trial.detectable and trial.train_score < 0.1 and not trial.resolvable
    delay = ts.truth_trial("logger_delay", 0, TABLE2, style="regulation", duration=10.0)
    assert delay.train_score > 1.0 and delay.resolvable


def test_the_logger_reads_the_channels_and_noise_of_the_librarys_synthetic_flights():
    assert ts.OUTPUTS == DEFAULT_OUTPUTS
    assert ts.NOISE == {c: DEFAULT_NOISE[c] for c in DEFAULT_OUTPUTS}


def test_the_table_names_library_candidates_and_their_parameters():
    assert set(ts.KINDS) == set(ts.KIND_CANDIDATES)
    outputs = ts.OUTPUTS
    for kind in ts.KINDS:
        assert set(ts.KIND_CANDIDATES[kind]) <= set(fx.ALL) | {"none"}
        injected = ts.draw(kind, ts.Dice(np.random.default_rng(5), 1.0, ts.NOISE, 30.0, 0.05, outputs))
        assert injected.candidates and set(injected.shared) <= set(injected.candidates)
        for candidate, values in injected.shared.items():
            assert set(values) <= {p.name for p in fx.params(candidate, outputs)}


def test_the_adapter_gives_library_flights_and_passes_seeds_through():
    a = independent_trial("servo_dynamics", 1000, R50_SI, style="sweep", duration=8.0)
    b = independent_trial("servo_dynamics", 0, R50_SI, style="sweep", duration=8.0)
    assert a.train.output_names == ts.OUTPUTS and a.train.n_samples == 161
    assert a.oracle == "actuator_lag" and a.primary.startswith("lag_") and a.value > 0
    assert a.eta[next(p.slot for p in fx.params("actuator_lag", ts.OUTPUTS) if p.name == a.primary)] == a.value
    assert a.train.metadata["kind"] == "servo_dynamics" and a.validate.metadata["role"] == "validate"
    assert not np.allclose(a.train.outputs, b.train.outputs)


def test_the_blind_check_flies_independent_trials_and_starts_its_oracle_at_the_shared_values():
    from jaxheli.benchmark.blind import scenario, trial_flights
    from jaxheli.benchmark.blind._trial import _oracle_row

    inj, train, validate, right, facts = trial_flights("independent", "drag", 3, scenario(3), duration=8.0, dt=0.05,
                                                       outputs=DEFAULT_OUTPUTS)
    assert inj.kind == "quadratic_drag" and right == ("quadratic_drag",) and inj.primary == "Xuu"
    assert facts["detectable"] == (facts["detectability"] > 1) and train.source != validate.source
    assert facts["resolvable"] == (facts["detectable"] and facts["detectability_train"] > 1)
    assert facts["structure_reach"] >= 0.0 and facts["structure_reach_train"] >= 0.0
    index, start, lower, upper = _oracle_row(inj.kind, inj, *fx.candidate_arrays(fx.ALL, DEFAULT_OUTPUTS))
    assert start[0, 0] == pytest.approx(np.clip(inj.value, lower[0, 0], upper[0, 0]))
    with pytest.raises(ValueError, match="unknown truth simulator"):
        trial_flights("other", "drag", 3, scenario(3), duration=8.0, dt=0.05, outputs=DEFAULT_OUTPUTS)


def test_wide_truths_leave_the_authors_box_in_every_coupling_and_the_pilot_still_flies_them():
    rng = np.random.default_rng(11)
    for reference in (TABLE2, R50_SI):
        for _ in range(20):
            theta = ts.wide_truth(reference, rng)
            assert set(ts.COUPLINGS) <= set(ts.outside_box(theta))
            A, B = ts.hover_model(theta)
            K = ts.lqr_gain(A, B, 0.05)
            Ad, Bd = (np.asarray(m) for m in scipy.signal.cont2discrete((A, B, np.eye(13), 0), 0.05)[:2])
            assert np.max(np.abs(np.linalg.eigvals(Ad - Bd @ K))) < 1.0
    assert ts.outside_box(TABLE2) == ()
    flight = ts.fly(ts.wide_truth(TABLE2, rng), ts.Effects(), style="sweep", duration=10.0, dt=0.05, seed=2,
                    noise=np.array([ts.NOISE[c] for c in ts.OUTPUTS]))
    assert np.all(np.isfinite(flight.measured)) and np.max(np.abs(flight.states[:, 4:6])) < 0.5
