"""Native vector env (kernel.advance_batch) vs independent single envs; sync and async modes."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import softhand_env  # noqa: F401
from softhand_env.envs import SoftHandVectorEnv

N = 4
# randomisation + observation noise exercise every per-env random stream
KWARGS = {"obs_mode": "proprio_tactile", "history_len": 2, "randomize": True}


def _actions(steps, seed=0):
    """Random actions; env 0 opens its fingers now and then (grasp lost -> autoreset)."""
    a = np.random.default_rng(seed).uniform(-1, 1, (steps, N, 2)).astype(np.float32)
    a[5:12, 0] = -1.0
    return a


def _compare_infos(i1, i2):
    assert sorted(i1) == sorted(i2)
    for key, v2 in i2.items():
        v1 = i1[key]
        if isinstance(v2, dict):
            _compare_infos(v1, v2)
        elif v2.dtype == object:
            for a, b in zip(v1, v2, strict=True):
                if isinstance(b, np.ndarray):
                    np.testing.assert_array_equal(a, b)
                else:
                    assert a == b, key
        else:
            assert v1.dtype == v2.dtype, key
            # same kernel code per system: equal to round-off (in practice bit-equal)
            np.testing.assert_allclose(v1, v2, rtol=1e-12, atol=1e-15, err_msg=key)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_native_matches_independent_single_envs(mode):
    env_id = "SoftHandReorient-v0"
    native = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point",
                          max_episode_steps=20, autoreset_mode=mode, **KWARGS)
    assert isinstance(native.unwrapped, SoftHandVectorEnv)
    single = SyncVectorEnv(
        [lambda: gym.make(env_id, max_episode_steps=20, **KWARGS) for _ in range(N)],
        autoreset_mode=mode,
    )
    o1, i1 = native.reset(seed=11)
    o2, i2 = single.reset(seed=11)
    np.testing.assert_array_equal(o1, o2)
    _compare_infos(i1, i2)
    ends = 0
    for a in _actions(60):
        o1, r1, te1, tr1, i1 = native.step(a)
        o2, r2, te2, tr2, i2 = single.step(a)
        np.testing.assert_allclose(o1, o2, rtol=1e-6, atol=1e-7)  # float32 observations
        np.testing.assert_allclose(r1, r2, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(te1, te2)
        np.testing.assert_array_equal(tr1, tr2)
        _compare_infos(i1, i2)
        ends += int(te1.sum() + tr1.sum())
    assert ends >= N + 1  # truncations of every env and at least one termination happened
    native.close()
    single.close()


def test_make_vec_spaces_metadata_and_no_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the current version (Gymnasium warns on make of -v0)
        envs = gym.make_vec("SoftHandPose-v1", num_envs=3, vectorization_mode="vector_entry_point")
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert envs.num_envs == 3 and envs.unwrapped.max_episode_steps == 400
    assert envs.single_observation_space.shape == (10,)
    assert envs.observation_space.shape == (3, 10) and envs.action_space.shape == (3, 2)
    assert envs.unwrapped.dt == pytest.approx(0.02)
    obs, _ = envs.reset(seed=0)
    assert obs in envs.observation_space
    obs, rewards, terminated, truncated, _ = envs.step(envs.action_space.sample())
    assert obs.dtype == np.float32 and rewards.dtype == np.float64
    assert terminated.dtype == np.bool_ and truncated.dtype == np.bool_
    assert len(set(map(float, envs.unwrapped.goals[:, 0]))) == 3  # per-env goals
    with pytest.raises(ValueError, match="finite"):
        envs.step(np.full((3, 2), np.nan, dtype=np.float32))
    envs.close()


def test_per_env_time_limit_and_next_step_autoreset():
    envs = SoftHandVectorEnv(num_envs=2, max_episode_steps=3, task="translate")
    envs.reset(seed=0)
    zero = np.zeros((2, 2), dtype=np.float32)
    envs.step(zero)
    # reset only env 1: its counter restarts, env 0 keeps counting
    envs.reset(options={"reset_mask": np.array([False, True])})
    truncated = [envs.step(zero)[3].tolist() for _ in range(3)]
    # env 0 reaches 3 steps first; on the next step it restarts (reward 0, not truncated)
    # while env 1 reaches its own limit
    assert truncated == [[False, False], [True, False], [False, True]]
    assert envs.unwrapped._steps.tolist() == [0, 3]
    obs, rewards, _, truncated, _ = envs.step(zero)
    assert truncated.tolist() == [False, False] and rewards[1] == 0.0
    assert envs.unwrapped._steps.tolist() == [1, 0]
    assert np.isfinite(obs).all()


def test_disabled_autoreset_with_reset_mask():
    envs = SoftHandVectorEnv(num_envs=2, autoreset_mode="Disabled", action_mode="absolute",
                             normalize_action=False)
    envs.reset(seed=0)
    a = np.radians([[-30.0, -30.0], [6.0, 6.0]])
    _, _, terminated, _, info = envs.step(a)
    assert terminated.tolist() == [True, False]
    assert info["termination_reason"][0] == "grasp_lost" and info["_termination_reason"][0]
    assert info["termination_reason"][1] is None  # in every info, None while running
    obs, info = envs.reset(options={"reset_mask": np.array([True, False])})
    assert info["_object_pose"].tolist() == [True, False]
    assert info["grasped"][0]
    _, _, terminated, _, _ = envs.step(np.radians([[6.0, 6.0], [6.0, 6.0]]))
    assert not terminated.any()


def test_sync_and_async_make_vec_agree():
    kwargs = {"num_envs": 2, "max_episode_steps": 10}
    sync = gym.make_vec("SoftHandTranslate-v0", vectorization_mode="sync", **kwargs)
    asyn = gym.make_vec("SoftHandTranslate-v0", vectorization_mode="async", **kwargs)
    o1, _ = sync.reset(seed=3)
    o2, _ = asyn.reset(seed=3)
    np.testing.assert_array_equal(o1, o2)
    for a in np.random.default_rng(0).uniform(-1, 1, (15, 2, 2)).astype(np.float32):
        o1, r1, te1, tr1, _ = sync.step(a)
        o2, r2, te2, tr2, _ = asyn.step(a)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(te1 | tr1, te2 | tr2)
    sync.close()
    asyn.close()


def test_vector_rgb_frames():
    envs = SoftHandVectorEnv(num_envs=2, task="pose", render_mode="rgb_array",
                             render_width=64, render_height=48)
    envs.reset(seed=0)
    frames = envs.render()
    assert len(frames) == 2 and frames[0].shape == (48, 64, 3) and frames[0].dtype == np.uint8
    with pytest.raises(ValueError, match="render_mode"):
        SoftHandVectorEnv(num_envs=2, render_mode="human")


def test_step_before_reset_raises_reset_needed_like_sync():
    from gymnasium.error import ResetNeeded

    native = SoftHandVectorEnv(num_envs=2, task="reorient")
    sync = gym.make_vec("SoftHandReorient-v0", num_envs=2, vectorization_mode="sync")
    for envs in (native, sync):
        with pytest.raises(ResetNeeded):
            envs.step(np.zeros((2, 2), dtype=np.float32))
    # a partial first reset is not enough either
    native.reset(seed=0, options={"reset_mask": np.array([True, False])})
    with pytest.raises(ResetNeeded):
        native.step(np.zeros((2, 2), dtype=np.float32))
    native.reset(seed=0)
    native.step(np.zeros((2, 2), dtype=np.float32))


def test_goal_option_applies_to_every_env_like_sync_and_per_env_rows():
    native = gym.make_vec("SoftHandTranslate-v0", num_envs=2,
                          vectorization_mode="vector_entry_point")
    sync = gym.make_vec("SoftHandTranslate-v0", num_envs=2, vectorization_mode="sync")
    o1, i1 = native.reset(seed=3, options={"goal": [0.004]})
    o2, i2 = sync.reset(seed=3, options={"goal": [0.004]})
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(i1["goal"], i2["goal"])
    assert i1["goal"].ravel().tolist() == [0.004, 0.004]
    a = np.random.default_rng(0).uniform(-1, 1, (2, 2)).astype(np.float32)
    np.testing.assert_array_equal(native.step(a)[0], sync.step(a)[0])
    _, info = native.reset(seed=3, options={"goal": [[0.004], [-0.002]]})
    assert info["goal"].ravel().tolist() == [0.004, -0.002]
    with pytest.raises(ValueError, match="unknown reset options"):
        native.reset(options={"gaol": [0.0]})
    with pytest.raises(ValueError, match="shape"):
        native.reset(options={"goal": [[0.0], [0.0], [0.0]]})


def test_native_vector_env_rejects_non_real_actions():
    native = SoftHandVectorEnv(num_envs=2, task="reorient")
    native.reset(seed=0)
    with pytest.raises(TypeError, match="action"):
        native.step(np.array([[1 + 1j, 0], [0, 0]]))
    with pytest.raises(ValueError, match="action"):
        native.step(np.zeros((3, 2), dtype=np.float32))
