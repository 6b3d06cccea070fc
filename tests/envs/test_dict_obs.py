"""Dict-observation variants (goal_obs, privileged_obs): blind part, rewards, vector env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import SyncVectorEnv
from stable_baselines3.common.env_checker import check_env
from stable_baselines3.common.vec_env import DummyVecEnv

import softhand_env  # noqa: F401
from agents.sb3.native_vec_env import NativeVecEnv
from softhand_env.envs.dict_obs import PRIVILEGED_NAMES
from softhand_env.envs.observation import ANGLE_SCALE, DN_SCALE, POSITION_SCALE

# randomisation + noise + history: every part of the blind observation is exercised
KWARGS = {"obs_mode": "proprio_tactile", "history_len": 2, "randomize": True}


def _actions(steps, n=None, seed=0):
    shape = (steps, 2) if n is None else (steps, n, 2)
    a = np.random.default_rng(seed).uniform(-1, 1, shape).astype(np.float32)
    a[10:30, ..., 0] = -1.0  # opens finger 1: the grasp is lost (termination)
    return a


@pytest.mark.parametrize("keys", [{"goal_obs": True}, {"privileged_obs": True},
                                  {"goal_obs": True, "privileged_obs": True}])
def test_blind_part_equals_plain_observation(keys):
    env_id = "SoftHandPose-v0"
    plain = gym.make(env_id, **KWARGS)
    wrapped = gym.make(env_id, **KWARGS, **keys)
    h = plain.unwrapped.config.layout.history_size
    o1, _ = plain.reset(seed=4)
    o2, _ = wrapped.reset(seed=4)
    ends = 0
    for t, a in enumerate(_actions(60)):
        if keys.get("goal_obs"):
            np.testing.assert_array_equal(o2["observation"], o1[:h])
            assert o2["observation"].dtype == np.float32
            # the goal entries moved to desired_goal (same scaled units)
            np.testing.assert_array_equal(o2["desired_goal"].astype(np.float32), o1[h:])
        else:
            np.testing.assert_array_equal(o2["observation"], o1)
        assert wrapped.observation_space.contains(o2), t
        o1, r1, te1, tr1, i1 = plain.step(a)
        o2, r2, te2, tr2, i2 = wrapped.step(a)
        assert (r1, te1, tr1) == (r2, te2, tr2)
        if te1 or tr1:
            ends += 1
            o1, _ = plain.reset()
            o2, _ = wrapped.reset()
    assert ends >= 1


def test_compute_reward_equals_step_reward():
    env = gym.make("SoftHandPose-v0", goal_obs=True, **KWARGS)
    obs, _ = env.reset(seed=2)
    compute = env.get_wrapper_attr("compute_reward")
    rows = []
    for a in _actions(80):
        obs, reward, terminated, truncated, info = env.step(a)
        # one transition; the reward is recomputed, not copied: exact up to the scaling of
        # the goals (g / s * s, a few ulp; measured max |difference| 4.4e-16 over 3000 random
        # steps of each goal task with randomisation): tolerance 1e-12
        assert compute(obs["achieved_goal"], obs["desired_goal"], info) == pytest.approx(
            reward, rel=0, abs=1e-12)
        rows.append((obs["achieved_goal"], obs["desired_goal"], info, reward))
        if terminated or truncated:
            obs, _ = env.reset()
    assert any(info["reward_failure"] < 0 for *_, info, _ in rows)  # a failure step
    ach = np.array([r[0] for r in rows])
    des = np.array([r[1] for r in rows])
    infos = np.array([r[2] for r in rows], dtype=object)
    rewards = np.array([r[3] for r in rows])
    # batched, as SB3's HerReplayBuffer calls it (infos: an object array of dicts)
    np.testing.assert_allclose(compute(ach, des, infos), rewards, rtol=1e-12, atol=1e-12)
    # relabelled to the achieved goal: every grasped step earns the success bonus
    task = env.unwrapped.task
    relabelled = compute(ach, ach, infos)
    grasped = np.array([i["grasped"] for i in infos])
    expected = (task.goal_weight + task.success_weight * grasped
                + np.array([i["reward_ctrl"] + i["reward_failure"] for i in infos]))
    np.testing.assert_allclose(relabelled, expected, rtol=1e-12, atol=1e-12)
    assert not np.allclose(relabelled, rewards)


def test_privileged_contents():
    env = gym.make("SoftHandReorient-v0", privileged_obs=True, **KWARGS)
    obs, info = env.reset(seed=9)
    for a in _actions(8):
        obs, *_, info = env.step(a)
    priv = obs["privileged"]
    assert priv.shape == (len(PRIVILEGED_NAMES) + 1,) and priv.dtype == np.float32
    pose = info["object_pose"]
    np.testing.assert_allclose(priv[:3], pose / [POSITION_SCALE, POSITION_SCALE, ANGLE_SCALE],
                               rtol=1e-6)
    np.testing.assert_allclose(priv[6:8], info["deformation"][:2] / DN_SCALE, rtol=1e-6)
    dev = priv[10:16] * 0.5  # relative deviations of the drawn parameters
    assert np.all(dev != 0) and np.all(np.abs(dev) <= 0.2 + 1e-6)  # preset half-widths <= 0.2
    np.testing.assert_allclose(priv[-1], (pose[2] - info["goal"][0]) / ANGLE_SCALE, rtol=1e-5)
    # the nominal hand: no deviation
    nominal = gym.make("SoftHandReorient-v0", privileged_obs=True)
    o, _ = nominal.reset(seed=0)
    np.testing.assert_array_equal(o["privileged"][10:16], 0.0)


def test_check_env_passes_and_bad_keywords():
    for keys in ({"goal_obs": True}, {"privileged_obs": True}):
        check_env(gym.make("SoftHandTranslate-v0", **keys))
    check_env(gym.make("SoftHand-v0", privileged_obs=True))
    with pytest.raises(ValueError, match="goal_obs=True needs a goal task"):
        gym.make("SoftHand-v0", goal_obs=True)
    with pytest.raises(TypeError, match="privileged_obs must be True or False"):
        gym.make("SoftHandTranslate-v0", privileged_obs="yes")


# the Random id draws each episode's parameters: the privileged deviations of restarted hands
@pytest.mark.parametrize("env_id", ["SoftHandPose-v0", "SoftHandPoseRandom-v0"])
def test_vector_env_matches_single_envs(env_id):
    n, keys = 3, {"goal_obs": True, "privileged_obs": True, "max_episode_steps": 15}
    native = gym.make_vec(env_id, num_envs=n,
                          vectorization_mode="vector_entry_point", **KWARGS, **keys)
    sync = SyncVectorEnv([lambda: gym.make(env_id, **KWARGS, **keys)
                          for _ in range(n)])
    assert native.single_observation_space == sync.single_observation_space
    o1, _ = native.reset(seed=5)
    o2, _ = sync.reset(seed=5)
    restarting = np.zeros(n, dtype=bool)
    checked = 0
    for a in _actions(40, n):
        for key in o2:
            np.testing.assert_allclose(o1[key], o2[key], rtol=1e-12, atol=1e-12, err_msg=key)
        o1, r1, te, tr, info = native.step(a)
        o2, r2, *_ = sync.step(a)
        np.testing.assert_allclose(r1, r2, rtol=1e-12, atol=1e-12)
        # batched compute_reward on the batched info (rows that restarted carry reward 0)
        got = native.compute_reward(o1["achieved_goal"], o1["desired_goal"], info)
        np.testing.assert_allclose(got[~restarting], r1[~restarting], rtol=0, atol=1e-12)
        checked += int((~restarting).sum())
        restarting = te | tr
    assert checked > 100


def test_native_sb3_vec_env_with_dict_observations_matches_dummy():
    n, keys = 3, {"goal_obs": True, "privileged_obs": True, "max_episode_steps": 15}
    dummy = DummyVecEnv([lambda: gym.make("SoftHandPose-v0", **KWARGS, **keys)
                         for _ in range(n)])
    native = NativeVecEnv(gym.make_vec("SoftHandPose-v0", num_envs=n,
                                       vectorization_mode="vector_entry_point",
                                       **KWARGS, **keys))
    dummy.seed(1)
    native.seed(1)
    o1, o2 = dummy.reset(), native.reset()
    ends = 0
    for a in _actions(40, n):
        for key in o1:
            np.testing.assert_allclose(o2[key], o1[key], rtol=1e-12, atol=1e-12, err_msg=key)
        o1, r1, d1, i1 = dummy.step(a)
        o2, r2, d2, i2 = native.step(a)
        np.testing.assert_array_equal(d1, d2)
        np.testing.assert_allclose(r2, r1, rtol=1e-6)
        for i in np.flatnonzero(d1):
            ends += 1
            for key, value in i1[i]["terminal_observation"].items():
                np.testing.assert_allclose(i2[i]["terminal_observation"][key], value,
                                           rtol=1e-12, atol=1e-12, err_msg=key)
    assert ends >= n
    # HER's call: compute_reward on env 0 with a batch
    got = native.env_method("compute_reward", o2["achieved_goal"], o2["desired_goal"],
                            np.array(i2, dtype=object), indices=[0])[0]
    want = dummy.env_method("compute_reward", o1["achieved_goal"], o1["desired_goal"],
                            np.array(i1, dtype=object), indices=[0])[0]
    np.testing.assert_allclose(got, want, rtol=1e-12)
