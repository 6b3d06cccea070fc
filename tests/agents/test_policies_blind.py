"""Blind-actor policies: the actor ignores privileged / achieved_goal, the critic reads them;
SAC + HER smoke runs (single env and the native VecEnv)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import PPO, SAC, HerReplayBuffer
from stable_baselines3.common.vec_env import DummyVecEnv

import softhand_env  # noqa: F401
from agents.sb3.native_vec_env import make_sb3_vec_env
from agents.sb3.policies import AsymmetricActorCriticPolicy, BlindActorSACPolicy, KeyConcat

HER_KWARGS = {"n_sampled_goal": 4, "goal_selection_strategy": "future", "copy_info_dict": True}


def _obs_batch(env, n=8, seed=0):
    """n observations of a rollout with random actions (a batch for the policy)."""
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        obs, *_ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out.append(obs)
    return {k: np.stack([o[k] for o in out]) for k in out[0]}


def _perturbed(batch, key, seed=1):
    rng = np.random.default_rng(seed)
    return {**batch, key: batch[key] + rng.normal(0, 5, batch[key].shape).astype(batch[key].dtype)}


def test_ppo_asymmetric_actor_ignores_privileged_and_critic_reads_it(tmp_path):
    env = gym.make("SoftHandReorient-v0", privileged_obs=True)
    model = PPO("AsymmetricPolicy", env, n_steps=64, batch_size=64, n_epochs=1, seed=0,
                policy_kwargs={"net_arch": {"pi": [32], "vf": [32]}})
    assert isinstance(model.policy, AsymmetricActorCriticPolicy)
    model.learn(128)  # trained weights, not just the initialisation
    batch = _obs_batch(env)
    other = _perturbed(batch, "privileged")
    policy = model.policy
    for deterministic in (True, False):
        th.manual_seed(0)
        a1, _ = model.predict(batch, deterministic=deterministic)
        th.manual_seed(0)
        a2, _ = model.predict(other, deterministic=deterministic)
        np.testing.assert_array_equal(a1, a2)
    t1, _ = policy.obs_to_tensor(batch)
    t2, _ = policy.obs_to_tensor(other)
    assert not th.allclose(policy.predict_values(t1), policy.predict_values(t2))
    # the blind observation does change the actions
    a3, _ = model.predict(_perturbed(batch, "observation"), deterministic=True)
    assert not np.allclose(a1, a3)
    # saved and loaded with its keys
    model.save(tmp_path / "m.zip")
    loaded = PPO.load(tmp_path / "m.zip")
    assert loaded.policy.pi_features_extractor.keys == ("observation",)
    assert loaded.policy.vf_features_extractor.keys == ("observation", "privileged")
    np.testing.assert_array_equal(loaded.predict(batch, deterministic=True)[0],
                                  model.predict(batch, deterministic=True)[0])


def test_sac_her_actor_ignores_achieved_goal_and_learns(tmp_path):
    env = gym.make("SoftHandReorient-v0", goal_obs=True, max_episode_steps=50)
    model = SAC("BlindActorPolicy", env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs=HER_KWARGS, learning_starts=100, batch_size=64, seed=0,
                policy_kwargs={"net_arch": [32, 32]})
    assert isinstance(model.policy, BlindActorSACPolicy)
    model.learn(300)  # smoke: rollouts, relabelling through compute_reward, updates
    assert model.num_timesteps == 300 and model.replay_buffer.size() > 0
    assert model.policy.actor.features_extractor.keys == ("observation", "desired_goal")
    assert "achieved_goal" in model.policy.critic.features_extractor.keys
    batch = _obs_batch(env)
    other = _perturbed(batch, "achieved_goal")
    a1, _ = model.predict(batch, deterministic=True)
    np.testing.assert_array_equal(a1, model.predict(other, deterministic=True)[0])
    assert not np.allclose(a1, model.predict(_perturbed(batch, "desired_goal"),
                                             deterministic=True)[0])
    t1, _ = model.policy.obs_to_tensor(batch)
    t2, _ = model.policy.obs_to_tensor(other)
    act = th.as_tensor(a1)
    with th.no_grad():
        q1, q2 = model.critic(t1, act)[0], model.critic(t2, act)[0]
    assert not th.allclose(q1, q2)
    model.save(tmp_path / "sac.zip")
    loaded = SAC.load(tmp_path / "sac.zip", env=DummyVecEnv([lambda: env]))
    assert loaded.policy.actor.features_extractor.keys == ("observation", "desired_goal")


def test_sac_her_smoke_on_the_native_vec_env():
    venv = make_sb3_vec_env("SoftHandTranslate-v0", 4, seed=0,
                            env_kwargs={"goal_obs": True, "max_episode_steps": 40},
                            vec_env="native")
    model = SAC("BlindActorPolicy", venv, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs=HER_KWARGS, learning_starts=200, batch_size=64,
                train_freq=1, gradient_steps=1, seed=0, policy_kwargs={"net_arch": [32, 32]})
    model.learn(400)
    assert model.num_timesteps == 400
    venv.close()


def test_key_errors():
    box = gym.make("SoftHandReorient-v0")
    with pytest.raises(TypeError, match="Dict observation space"):
        PPO("AsymmetricPolicy", box)
    env = gym.make("SoftHandReorient-v0", privileged_obs=True)
    with pytest.raises(ValueError, match="no key"):
        KeyConcat(env.observation_space, ["desired_goal"])
    with pytest.raises(ValueError, match="sets share_features_extractor itself"):
        PPO("AsymmetricPolicy", env, policy_kwargs={"share_features_extractor": True})
    her_env = gym.make("SoftHandReorient-v0", goal_obs=True)
    compute = her_env.get_wrapper_attr("compute_reward")
    with pytest.raises(ValueError, match="copy_info_dict"):
        compute(np.zeros((2, 1)), np.zeros((2, 1)), np.array([{}, {}], dtype=object))
