"""Goal curriculum: the task's goal scale, through Gymnasium, SB3 VecEnvs and a callback."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

import softhand_env  # noqa: F401
from agents.sb3.curriculum import GoalCurriculumCallback, set_goal_scale
from agents.sb3.native_vec_env import NativeVecEnv, make_sb3_vec_env

ENV_ID = "SoftHandPose-v0"
N = 3


def _goals(venv, steps=40):
    """Goals of every episode started over ``steps`` random steps (reset goals included)."""
    venv.reset()
    goals = [np.array(venv.get_attr("goal")) if not isinstance(venv, NativeVecEnv)
             else venv.get_attr("goals")[0]]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        _, _, dones, infos = venv.step(rng.uniform(-1, 1, (N, 2)).astype(np.float32))
        goals.append(np.array([i["goal"] for i in infos]))
    return np.concatenate(goals)


def test_scale_one_is_todays_sampling_and_smaller_scales_shrink_the_range():
    env = gym.make(ENV_ID)
    task = env.unwrapped.task
    ranges = np.array([t.goal_range for t in task.targets])
    g0 = [env.reset(seed=s)[1]["goal"] for s in range(5)]
    task.set_goal_scale(1.0)
    np.testing.assert_array_equal(g0, [env.reset(seed=s)[1]["goal"] for s in range(5)])
    task.set_goal_scale(0.25)
    g = np.array([env.reset(seed=s)[1]["goal"] for s in range(5)])
    # same uniform draws, a quarter of the range
    np.testing.assert_allclose(g, 0.25 * np.array(g0), rtol=1e-12)
    assert np.all(np.abs(g) <= 0.25 * ranges)
    # a goal given explicitly is kept
    assert env.reset(options={"goal": [0.005, 0.1]})[1]["goal"].tolist() == [0.005, 0.1]
    for bad in (0.0, 1.5, float("nan"), "1"):
        with pytest.raises(ValueError, match="goal scale"):
            task.set_goal_scale(bad)


def test_set_goal_scale_on_dummy_and_native_vec_envs_gives_the_same_goals():
    kw = {"max_episode_steps": 10}
    dummy = VecNormalize(DummyVecEnv([lambda: gym.make(ENV_ID, **kw) for _ in range(N)]))
    native = VecNormalize(make_sb3_vec_env(ENV_ID, N, None, kw, "native"))
    for venv in (dummy, native):
        venv.seed(3)
        set_goal_scale(venv, 0.1)
    g1, g2 = _goals(dummy.venv), _goals(native.venv)
    np.testing.assert_allclose(g1, g2, rtol=1e-12)
    ranges = np.array([t.goal_range for t in native.get_attr("task")[0].targets])
    assert len(g1) > 3 * N and np.all(np.abs(g1) <= 0.1 * ranges)
    with pytest.raises(ValueError, match="no goal"):
        set_goal_scale(make_sb3_vec_env("SoftHand-v0", 2, 0, {}, "native"), 0.5)


def test_subproc_vec_env_is_refused():
    venv = SubprocVecEnv([lambda: gym.make(ENV_ID)], start_method="fork")
    try:
        with pytest.raises(ValueError, match="in-process"):
            set_goal_scale(venv, 0.5)
    finally:
        venv.close()


def test_callback_widens_the_range_linearly():
    venv = make_sb3_vec_env(ENV_ID, 4, 0, {"max_episode_steps": 20}, "native")
    scales = []

    class Spy(GoalCurriculumCallback):
        def _apply(self):
            super()._apply()
            scales.append((self.num_timesteps, venv.get_attr("task")[0].goal_scale))

    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=128, n_epochs=1, seed=0)
    model.learn(512, callback=Spy(start=0.2, until=0.5))
    assert scales[0] == (0, 0.2)
    for t, s in scales:
        assert s == pytest.approx(min(0.2 + 0.8 * t / 256, 1.0))
    assert scales[-1][1] == 1.0
    with pytest.raises(ValueError, match="start must be"):
        GoalCurriculumCallback(start=0.0)


def test_goal_scale_on_the_native_vec_env_of_a_random_id():
    venv = VecNormalize(make_sb3_vec_env("SoftHandPoseRandom-v0", N, None,
                                         {"max_episode_steps": 10}, "native"))
    venv.seed(1)
    set_goal_scale(venv, 0.2)
    goals = _goals(venv.venv)
    ranges = np.array([t.goal_range for t in venv.get_attr("task")[0].targets])
    assert len(goals) > 3 * N and np.all(np.abs(goals) <= 0.2 * ranges)
    assert np.all(np.abs(goals).max(axis=0) > 0.05 * ranges)  # goals do vary
