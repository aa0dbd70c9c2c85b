"""Further starts of the effect fits and the nuisance slots every fit frees: the arrays against hand-built ones."""

import numpy as np

from jaxheli.effects import plant as augmented, registry as effects
from jaxheli.gap.fit_effect import with_reference
from jaxheli.gap.candidates import best_rows
from jaxheli.synth.piloted import DEFAULT_OUTPUTS

OUT = DEFAULT_OUTPUTS
PAD = augmented.size(OUT)


def test_start_rows_try_the_axes_together_where_asked_then_each_alone():
    rows = effects.start_rows("control_saturation", OUT)
    expected = np.ones((11, 4))
    for t, value in enumerate((25.0, 90.0)):
        expected[1 + 5 * t] = value
        for axis in range(4):
            expected[2 + 5 * t + axis, axis] = value
    np.testing.assert_array_equal(rows, expected)
    drag = effects.start_rows("quadratic_drag", OUT)
    np.testing.assert_array_equal(drag, [[0, 0, 0, 0], [-3, -3, 0, 0], [-3, 0, 0, 0], [0, -3, 0, 0]])
    delay = effects.start_rows("input_delay", OUT)  # each axis alone: never all four delayed at once
    np.testing.assert_array_equal(delay, np.where(np.r_[np.zeros((1, 4)), np.eye(4)] > 0, 0.15, 0.01))
    mis = effects.start_rows("sensor_misalignment", OUT)  # the IMU's yaw alone at +-0.1 rad
    np.testing.assert_array_equal(mis[:, 0], [0.0, 0.1, -0.1])
    np.testing.assert_array_equal(mis[:, 1:], 0.0)
    noise = effects.start_rows("process_noise", OUT)  # the gusts' correlation time also from 3 s
    ps = effects.params("process_noise", OUT)
    np.testing.assert_array_equal(noise, [[p.start for p in ps], [3.0 if p.name == "gust_tau" else p.start for p in ps]])
    bias = effects.params("output_bias_drift", OUT)  # the walk's reversion also from 0.5 1/s (a wander of 2 s)
    np.testing.assert_array_equal(effects.start_rows("output_bias_drift", OUT),
                                  [[p.start for p in bias], [0.5 if p.name == "reversion" else p.start for p in bias]])
    ps = effects.params("rotor_speed_coupling", OUT)
    np.testing.assert_array_equal(effects.start_rows("rotor_speed_coupling", OUT), [[p.start for p in ps]])


def test_tried_arrays_repeat_each_candidate_per_start_and_pad_to_the_joint_shape():
    index, start, lower, upper = effects.candidate_arrays(effects.ALL, OUT)
    t_index, t_start, t_lower, t_upper, owner = effects.tried_arrays(effects.ALL, OUT)
    counts = [len(effects.start_rows(e, OUT)) for e in effects.ALL]
    np.testing.assert_array_equal(owner, np.repeat(np.arange(len(effects.ALL)), counts))
    np.testing.assert_array_equal(t_index, index[owner])
    np.testing.assert_array_equal(t_lower, lower[owner])
    np.testing.assert_array_equal(t_upper, upper[owner])
    for c, name in enumerate(effects.ALL):
        rows = effects.start_rows(name, OUT)
        np.testing.assert_array_equal(t_start[owner == c, : rows.shape[1]], rows)
        assert np.all(t_start[owner == c, rows.shape[1]:] == 0)
    shape = effects.joint_shape(effects.ALL, OUT, 3)
    assert shape[0] == sum(counts)
    padded = effects.tried_arrays(effects.ALL, OUT, shape=(shape[0] + 2, shape[1]))
    assert padded[0].shape == (shape[0] + 2, shape[1]) and list(padded[4][-3:]) == [owner[-1]] * 3
    np.testing.assert_array_equal(padded[1][-1, : t_start.shape[1]], t_start[-1])


def test_best_rows_keep_the_least_training_rss_start_of_each_candidate():
    rng = np.random.default_rng(0)
    owner = np.array([0, 0, 0, 1, 2, 2, 1])
    rss = rng.uniform(1, 2, size=1 + owner.size)
    keep = best_rows(rss, owner)
    assert keep[0] == 0 and len(keep) == 4
    for c in range(3):
        rows = [r + 1 for r in range(owner.size) if owner[r] == c]
        assert keep[1 + c] == min(rows, key=lambda r: rss[r])


def test_the_nuisance_filter_cut_is_freed_in_every_row_once():
    slot, start, lower, upper = effects.nuisance_arrays(OUT)
    cut = next(p for p in effects.params("process_noise", OUT) if p.name == "state_noise_cut")
    assert list(slot) == [cut.slot] and list(start) == [cut.start] and list(upper) == [cut.bound]
    index, start_, lower_, upper_ = effects.candidate_arrays(effects.ALL, OUT)
    cand = with_reference(index, start_, lower_, upper_, PAD, effects.nuisance_arrays(OUT))
    idx = np.asarray(cand.index)
    assert idx.shape == (1 + len(effects.ALL), index.shape[1] + 1)
    assert np.all(idx[0, :-1] == PAD) and idx[0, -1] == cut.slot  # the reference re-tunes the filter too
    assert np.all(np.sum(idx == cut.slot, axis=1) == 1)  # exactly once per row
    noise = 1 + effects.ALL.index("process_noise")
    assert idx[noise, -1] == PAD and float(cand.upper[noise, -1]) == 0.0  # its own column frees it
    others = [r for r in range(1, idx.shape[0]) if r != noise]
    assert np.all(np.asarray(cand.start)[others, -1] == cut.start)


def test_best_rows_break_near_ties_by_parsimony_not_by_noise():
    owner = np.array([0, 0, 0])
    rss = np.array([1.0, 109.42, 109.01, 150.0])  # reference, then three starts of one candidate
    size = np.array([0.0, 0.2, 0.5, 0.0])
    assert list(best_rows(rss, owner, size)) == [0, 1]  # within START_TIE_PCT of the least RSS: the smaller
    far = rss.copy()
    far[2] = 100.0  # clearly better fit: kept despite its size
    assert list(best_rows(far, owner, size)) == [0, 2]
    assert list(best_rows(rss, owner)) == [0, 2]  # without sizes: the least RSS
