"""The effect registry: the frozen ``eta`` layout, a ninth effect picked up from its record alone, and the
airframe terms against a hand-written numpy step."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from jaxheli.effects import registry
from jaxheli.effects.catalogue import EFFECTS, QUADRATIC_DRAG
from jaxheli.effects.plant import GUST_STATES, layout, make_plant, no_effect
from jaxheli.effects.record import Draw, Effect, Group, Param, Registry, Term
from jaxheli.benchmark.blind import sample_injection
from jaxheli.model import STATE_NAMES, TABLE2, build_ab
from jaxheli.synth.piloted import DEFAULT_NOISE, DEFAULT_OUTPUTS

OUT = DEFAULT_OUTPUTS
DT = 0.05
K = len(OUT)
R = OUT.index("r")


def _offset(plant, y, t):
    return y.at[R].add(plant.group("offset")[0])


def _remove_offset(plant, y, t):
    return y.at[:, R].add(-plant.group("offset")[0])


GYRO_OFFSET = Effect(
    name="gyro_offset",
    groups=(Group("offset", 1),),
    eta_order=8,
    params=lambda outputs, at: (Param(at("offset", 0), "offset_r", "rad/s", "r", 0.0, False, 0.1),),
    terms=(Term("reading", _offset, _remove_offset),),
    inject=lambda dice: Draw({"offset_r": dice.sign * dice.rng.uniform(0.01, 0.02)}, "offset_r"),
)
"""A toy ninth effect: a constant offset on the yaw-rate gyro."""

NINE = Registry(EFFECTS.effects + (GYRO_OFFSET,))
E = EFFECTS.size(OUT)


def test_layout_is_the_historical_one():
    sizes = {"delay": 4, "lag": 4, "sat": 4, "drag": 4, "rotor": 2, "gust": 3, "mis": 6, "bias": K, "drift": K,
             "walk": K, "revert": 1}
    stops = np.cumsum(list(sizes.values()))
    assert layout(OUT) == {g: slice(int(stop - n), int(stop)) for (g, n), stop in zip(sizes.items(), stops)}
    expected = np.zeros(E)
    expected[[layout(OUT)["rotor"].start + 1, layout(OUT)["gust"].start + 1]] = [0.5, 1.0]
    np.testing.assert_array_equal(no_effect(OUT), expected)
    assert registry.ALL == ("input_delay", "actuator_lag", "output_bias_drift", "process_noise", "quadratic_drag",
                            "control_saturation", "rotor_speed_coupling", "sensor_misalignment")
    assert [t.apply.__name__ for t in EFFECTS.terms(("command", "servo"))] == ["_delay", "_saturate", "_lag"]


def test_the_bias_walks_on_rates_and_attitudes_only():
    """Each output channel has a bias and a drift; only the gyros' and attitudes' biases walk (velocities keep their
    walk slots at zero: a velocity walk and a slow wind look alike within a restart segment)."""
    names = [p.name for p in registry.params("output_bias_drift", OUT)]
    for c in OUT:
        assert {f"bias_{c}", f"drift_{c}"} <= set(names)
    assert [n for n in names if n.startswith("walk_")] == [f"walk_{c}" for c in OUT if c not in ("u", "v", "w")]
    assert {p.slot for p in registry.params("output_bias_drift", OUT)} < set(range(*layout(OUT)["bias"].indices(E))) \
        | set(range(*layout(OUT)["drift"].indices(E))) | set(range(*layout(OUT)["walk"].indices(E))) \
        | set(range(*layout(OUT)["revert"].indices(E)))


def test_a_ninth_effect_is_laid_out_and_parameterised_from_its_record_alone():
    assert NINE.names == registry.ALL + ("gyro_offset",)
    assert NINE.layout(OUT) == layout(OUT) | {"offset": slice(E, E + 1)}
    np.testing.assert_array_equal(NINE.no_effect(OUT), np.r_[no_effect(OUT), 0.0])
    assert NINE.params("gyro_offset", OUT) == (Param(E, "offset_r", "rad/s", "r", 0.0, False, 0.1),)
    for name in registry.ALL:
        assert NINE.params(name, OUT) == registry.params(name, OUT)


def test_a_ninth_effect_acts_in_the_plant_and_leaves_the_other_eight_unchanged():
    eight = no_effect(OUT)
    for kind in registry.ALL:  # every effect at once
        eta = sample_injection(kind, 3).eta
        eight = np.where(eta != no_effect(OUT), eta, eight)
    sticks = jnp.asarray(np.random.default_rng(0).normal(0.0, 0.2, (120, 4)))
    wind = jnp.asarray(np.random.default_rng(1).normal(0.0, 0.3, (120, 3)))
    t = DT * jnp.arange(120)

    def fly(eta, reg):
        plant = make_plant(jnp.asarray(TABLE2), jnp.asarray(eta), DT, OUT, registry=reg)

        def step(carry, inputs):
            x, history, servo, rotor = carry
            stick, w, time = inputs
            history, servo = plant.actuate(history, servo, stick)
            x_next, rotor = plant.advance(x, rotor, servo, w)
            return (x_next, history, servo, rotor), (x, plant.measure(x, time))

        history, servo, rotor = plant.init_actuators()
        _, (x, y) = jax.lax.scan(step, (jnp.zeros(13), history, servo, rotor), (sticks, wind, t))
        return np.asarray(x), np.asarray(y), np.asarray(plant.unmeasure(y, t))

    x8, y8, back8 = fly(eight, EFFECTS)
    assert np.max(np.abs(y8 - fly(no_effect(OUT), EFFECTS)[1])) > 1e-2  # the eight effects do act
    x9, y9, back9 = fly(np.r_[eight, 0.0], NINE)
    np.testing.assert_array_equal(x9, x8)
    np.testing.assert_array_equal(y9, y8)
    np.testing.assert_array_equal(back9, back8)
    x9, y9, back9 = fly(np.r_[eight, 0.02], NINE)
    np.testing.assert_array_equal(x9, x8)
    np.testing.assert_allclose(y9 - y8, np.outer(np.ones(120), 0.02 * np.eye(K)[R]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(back9, back8, atol=1e-14)


def test_a_ninth_effect_is_drawn_by_its_sampler_and_the_others_draw_as_before():
    eta, draw = NINE.inject("gyro_offset", 4, OUT, DEFAULT_NOISE, 30.0)
    assert draw.primary == "offset_r" and 0.01 <= abs(draw.values["offset_r"]) <= 0.02
    np.testing.assert_array_equal(eta, np.r_[no_effect(OUT), draw.values["offset_r"]])
    for kind in registry.ALL:
        eta, draw = NINE.inject(kind, 4, OUT, DEFAULT_NOISE, 30.0)
        old = sample_injection(kind, 4)
        np.testing.assert_array_equal(eta, np.r_[old.eta, 0.0])
        assert (draw.primary, draw.values[draw.primary], draw.gust) == (old.primary, old.value, old.gust)


def test_registry_rejects_clashes():
    with pytest.raises(ValueError, match="group"):
        Registry(EFFECTS.effects + (dataclasses.replace(GYRO_OFFSET, groups=(Group("drag", 1),)),))
    with pytest.raises(ValueError, match="eta_order"):
        Registry(EFFECTS.effects + (dataclasses.replace(GYRO_OFFSET, eta_order=3),))
    with pytest.raises(ValueError, match="stage"):
        Registry((dataclasses.replace(GYRO_OFFSET, terms=(Term("rotor", _offset),)),))
    trespass = dataclasses.replace(GYRO_OFFSET, params=lambda outputs, at: (Param(at("drag", 0), "x", "-", "-", 0, 0),))
    with pytest.raises(ValueError, match="not one of its own"):
        Registry((trespass,)).params("gyro_offset", OUT)


def test_drag_and_rotor_speed_step_match_a_numpy_reference():
    xuu, yvv, wind_u, wind_v, gain, tau = -2.0, 1.5, 0.6, -0.9, 3.0, 0.4
    eta = no_effect(OUT)
    eta[layout(OUT)["drag"]] = xuu, yvv, wind_u, wind_v
    eta[layout(OUT)["rotor"]] = gain, -tau  # the time constant acts through its magnitude
    plant = make_plant(jnp.asarray(TABLE2), jnp.asarray(eta), DT, OUT)
    A, B = (np.asarray(M) for M in build_ab(TABLE2))
    wind_in = -A[:, [STATE_NAMES.index(s) for s in GUST_STATES]]
    n = A.shape[0]
    big = np.zeros((n + 7, n + 7))
    big[:n, :n], big[:n, n:n + 4], big[:n, n + 4:] = A, B, wind_in
    expm = scipy.linalg.expm(big * DT)
    Ad, Bd, Ed = expm[:n, :n], expm[:n, n:n + 4], expm[:n, n + 4:]
    rng = np.random.default_rng(5)
    x, u, w = rng.normal(0.0, 0.5, n), rng.normal(0.0, 0.2, 4), rng.normal(0.0, 0.3, 3)
    rotor = 0.7
    t = tau + 1e-6
    rotor_next = (t * rotor + DT * gain * u[3]) / (t + DT)
    extra = np.zeros(n)
    iu, iv, ir = (STATE_NAMES.index(s) for s in ("u", "v", "r"))
    air_u, air_v = x[iu] - wind_u, x[iv] - wind_v  # drag on the airspeed, less its value at trim (x = 0)
    extra[iu] = xuu * (air_u * abs(air_u) + wind_u * abs(wind_u))
    extra[iv], extra[ir] = yvv * (air_v * abs(air_v) + wind_v * abs(wind_v)), rotor_next
    states = tuple(jnp.asarray(rotor) if term.init else None for term in EFFECTS.terms(("airframe",)))
    got, (_, got_rotor) = plant.advance(jnp.asarray(x), states, jnp.asarray(u), jnp.asarray(w))
    np.testing.assert_allclose(got, Ad @ x + Bd @ u + Ed @ w + DT * extra, rtol=1e-10, atol=1e-12)
    assert float(got_rotor) == pytest.approx(rotor_next, rel=1e-14)
    alone = make_plant(jnp.asarray(TABLE2), jnp.asarray(eta[layout(OUT)["drag"]]), DT, OUT,
                       registry=Registry((QUADRATIC_DRAG,)))  # a registry of one effect: drag only
    history, servo, rotor_states = alone.init_actuators()
    assert history == () and rotor_states == (None,)
    np.testing.assert_array_equal(alone.actuate(history, servo, jnp.asarray(u))[1], u)
    extra[ir] = 0.0
    np.testing.assert_allclose(alone.advance(jnp.asarray(x), rotor_states, jnp.asarray(u), jnp.asarray(w))[0],
                               Ad @ x + Bd @ u + Ed @ w + DT * extra, rtol=1e-10, atol=1e-12)
