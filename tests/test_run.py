"""The driver: a killed and resumed run equals an uninterrupted one bitwise; vmapped trials equal single
runs; checkpoints refuse other settings."""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxheli.optim import run
from jaxheli.optim.ga import GA
from jaxheli.optim.iwo import IWO
from jaxheli.optim.run import minimize, minimize_trials

LOWER = np.array([-1.0, -2.0, 0.5, -3.0])
UPPER = np.array([1.0, 2.0, 0.5, 3.0])  # axis 2 pinned


def bowl(thetas):
    """A tilted quadratic with its minimum inside the box, NaN in one corner."""
    cost = jnp.sum((thetas - jnp.array([0.3, -0.7, 0.5, 1.1])[None, :]) ** 2 * jnp.arange(1.0, 5.0)[None, :], axis=1)
    return jnp.where(thetas[:, 0] > 0.9, jnp.nan, cost)


TRACED = []


def traced_bowl(thetas):
    """:func:`bowl`, noting the batch shape each time it is traced."""
    TRACED.append(thetas.shape)
    return bowl(thetas)


IWO50 = IWO(LOWER, UPPER, iterations=50)


def _assert_same(a, b):
    leaves_a, tree_a = jax.tree_util.tree_flatten(a)
    leaves_b, tree_b = jax.tree_util.tree_flatten(b)
    assert tree_a == tree_b
    for x, y in zip(leaves_a, leaves_b):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_killed_run_resumes_bitwise(tmp_path, monkeypatch):
    TRACED.clear()
    reference = minimize(IWO50, traced_bowl, jax.random.key(5), chunk=20, progress=False)
    assert reference.history.shape == (50,)
    # one trace for init, one per chunk length (20, then the last 10): the chunks are jitted once; the seeds are
    # scored score_batch (max_population per device) at a time
    assert TRACED == [(20, 4), (IWO50.score_batch, 4), (IWO50.score_batch, 4)]

    path = tmp_path / "iwo.eqx"
    save, chunk = run._save, run._chunk
    saves, chunks = [], []

    def save_then_die(*args):
        save(*args)
        saves.append(args[0])
        if len(saves) == 2:
            raise KeyboardInterrupt  # killed right after the second checkpoint

    monkeypatch.setattr(run, "_save", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        minimize(IWO50, traced_bowl, jax.random.key(5), chunk=20, progress=False, checkpoint=path, resume=True)
    assert json.loads((tmp_path / "iwo.eqx.json").read_text())["iteration"] == 40
    assert not (tmp_path / "iwo.eqx.tmp").exists()
    assert run._verified(path)[0]["iteration"] == 40  # the checkpoint left behind is whole (checksum holds)
    (tmp_path / "iwo.eqx.tmp").write_bytes(b"torn")  # as if killed in the middle of the next write

    monkeypatch.setattr(run, "_save", save)
    monkeypatch.setattr(run, "_chunk", lambda *a: chunks.append(a[3]) or chunk(*a))
    # the same key as raw data: a checkpoint stores raw key data, so both spellings resume
    resumed = minimize(IWO50, traced_bowl, jax.random.PRNGKey(5), chunk=20, progress=False, checkpoint=path,
                       resume=True)
    assert chunks == [10]
    _assert_same(resumed, reference)
    assert json.loads((tmp_path / "iwo.eqx.json").read_text())["iteration"] == 50
    # resuming traces the initial state once more for its shapes (eval_shape, nothing compiled)
    assert TRACED == [(20, 4), (IWO50.score_batch, 4), (IWO50.score_batch, 4), (20, 4)]


def test_checkpoint_refuses_other_settings(tmp_path):
    opt = IWO50
    path = tmp_path / "run.eqx"
    minimize(opt, traced_bowl, jax.random.key(5), iterations=20, chunk=20, progress=False, checkpoint=path)
    with pytest.raises(ValueError, match="hyperparameters"):
        minimize(dataclasses.replace(opt, sigma_final=0.01), traced_bowl, jax.random.key(5), progress=False,
                 checkpoint=path, resume=True)
    with pytest.raises(ValueError, match="key"):
        minimize(opt, traced_bowl, jax.random.key(6), progress=False, checkpoint=path, resume=True)
    # without resume the checkpoint is overwritten by a fresh run
    fresh = minimize(opt, traced_bowl, jax.random.key(6), iterations=20, chunk=20, progress=False, checkpoint=path)
    assert json.loads((tmp_path / "run.eqx.json").read_text())["key"] == np.asarray(
        jax.random.key_data(jax.random.key(6))).tolist()
    assert fresh.history.shape == (20,)


def _flip_last_byte(data: bytes) -> bytes:
    return data[:-1] + bytes([data[-1] ^ 1])


def _edit_best_cost(data: bytes) -> bytes:
    seal, header, payload = data.split(b"\n", 2)
    edited = json.loads(header) | {"best_cost": 0.0}
    return b"\n".join([seal, json.dumps(edited).encode(), payload])


@pytest.mark.parametrize(
    ("damage", "match"),
    [
        (_flip_last_byte, "corrupt checkpoint: its .* bytes do not match the stored SHA-256"),
        (_edit_best_cost, "corrupt checkpoint"),
        (lambda data: data[: len(data) // 2], "corrupt checkpoint"),
        (lambda data: b"", r"not a jaxheli optimiser checkpoint \(empty file\)"),
        (lambda data: b"\x00\x01garbage", r"not a jaxheli optimiser checkpoint \(no header\)"),
    ],
    ids=["flipped", "edited", "truncated", "empty", "garbage"],
)
def test_damaged_checkpoint_is_refused_naming_it(tmp_path, damage, match):
    path = tmp_path / "run.eqx"
    minimize(IWO50, traced_bowl, jax.random.key(5), iterations=20, chunk=20, progress=False, checkpoint=path)
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(ValueError, match=rf"run\.eqx: {match}"):
        minimize(IWO50, traced_bowl, jax.random.key(5), progress=False, checkpoint=path, resume=True)


def test_progress_bar_moves_every_generation_and_changes_nothing(monkeypatch):
    moves = []

    class Bar(run.tqdm):
        def update(self, n=1):
            moves.append(n)
            return super().update(n)

    monkeypatch.setattr(run, "tqdm", Bar)
    quiet = minimize(IWO50, traced_bowl, jax.random.key(7), chunk=20, progress=False)
    shown = minimize(IWO50, traced_bowl, jax.random.key(7), chunk=20, progress=True)
    assert moves == [1] * 50
    _assert_same(shown, quiet)


@pytest.mark.parametrize("opt", [IWO50, GA(LOWER, UPPER, iterations=50)], ids=["iwo", "ga"])
def test_trials_equal_single_runs(opt):
    shapes = []

    def cost(thetas):
        shapes.append(thetas.shape)
        return traced_bowl(thetas)

    keys = jax.random.split(jax.random.key(11), 3)
    trials = minimize_trials(opt, cost, keys, chunk=25, progress=False)
    # IWO scores the three trials' real seeds together, max_population at a time; GA its whole flat buffer
    assert shapes[-1] == ((opt.score_batch, 4) if isinstance(opt, IWO) else (3 * (opt.population - opt.elite), 4))
    assert trials.history.shape == (3, 50) and trials.best_theta.shape == (3, 4)
    for k in range(3):
        single = minimize(opt, traced_bowl, keys[k], chunk=25, progress=False)
        _assert_same(jax.tree_util.tree_map(lambda x: x[k], trials), single)
    assert np.all(np.asarray(trials.best_theta)[:, 2] == 0.5)
    assert np.all(np.isfinite(np.asarray(trials.best_cost)))


def test_bad_arguments():
    opt = IWO(LOWER, UPPER)
    with pytest.raises(ValueError):
        minimize(opt, bowl, jax.random.split(jax.random.key(0), 2), progress=False)
    with pytest.raises(ValueError):
        minimize_trials(opt, bowl, jax.random.key(0), progress=False)
    with pytest.raises(ValueError):
        minimize(opt, bowl, jax.random.key(0), chunk=0, progress=False)
    with pytest.raises(TypeError):
        minimize_trials(opt, bowl, jax.random.split(jax.random.key(0), 2), chunks=3)
    with pytest.raises(ValueError, match="shape"):
        minimize(opt, lambda th: jnp.zeros((th.shape[0], 2)), jax.random.key(0), progress=False)
