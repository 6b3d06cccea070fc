"""Determinism: the same seed and actions give bit-identical trajectories in other
processes (Stable-Baselines3 ``SubprocVecEnv``, Gymnasium ``AsyncVectorEnv`` with fresh
``spawn`` interpreters) and after any earlier episodes (no state leaks through ``reset``:
PID integral, observation history, randomised parameters, grasp cache, random streams).

Randomisation, grasp noise, observation noise, tactile channels and a 3-frame history are all
on, so every per-episode quantity is exercised; assertions are exact (bit-identical).
"""

from __future__ import annotations

import functools

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AsyncVectorEnv, SyncVectorEnv

import softhand_env  # noqa: F401  (registers the environments)
from softhand_env.envs import SoftHandVectorEnv

KW = {
    "randomize": True,
    "reset_noise_deg": 1.0,
    "obs_noise": 0.02,
    "history_len": 3,
    "obs_mode": "proprio_tactile",
}
# "module:id" makes the id resolvable in a fresh interpreter (the worker imports softhand_env)
POSE = "softhand_env:SoftHandPose-v0"


def _actions(n_steps, n_envs=None, seed=0):
    shape = (n_steps, 2) if n_envs is None else (n_steps, n_envs, 2)
    return np.random.default_rng(seed).uniform(-1, 1, shape).astype(np.float32)


# ------------------------------------------------------------------ across processes
def test_sb3_subprocvecenv_is_bit_identical_to_single_envs():
    from stable_baselines3.common.vec_env import SubprocVecEnv

    n, seed, steps = 2, 7, 40
    make = functools.partial(gym.make, POSE, max_episode_steps=12, **KW)
    venv = SubprocVecEnv([make] * n)  # forkserver: workers are fresh processes
    try:
        venv.seed(seed)  # env i gets seed + i at the next reset (SB3 convention)
        obs = venv.reset()
        singles = [make() for _ in range(n)]
        single_obs = np.stack([e.reset(seed=seed + i)[0] for i, e in enumerate(singles)])
        np.testing.assert_array_equal(obs, single_obs)
        dones_seen = 0
        for actions in _actions(steps, n):
            obs, rewards, dones, infos = venv.step(actions)
            for i, env in enumerate(singles):
                o, r, te, tr, _ = env.step(actions[i])
                assert rewards[i] == r and dones[i] == (te or tr)
                if te or tr:
                    np.testing.assert_array_equal(infos[i]["terminal_observation"], o)
                    assert infos[i]["TimeLimit.truncated"] == (tr and not te)
                    o, _ = env.reset()
                    dones_seen += 1
                np.testing.assert_array_equal(obs[i], o)
        assert dones_seen >= n  # every env went through at least one autoreset
    finally:
        venv.close()


def test_gymnasium_async_spawn_is_bit_identical_to_sync():
    n, seed = 2, 13
    fns = [functools.partial(gym.make, POSE, max_episode_steps=12, **KW)] * n
    asyn = AsyncVectorEnv(fns, context="spawn")
    sync = SyncVectorEnv(fns)
    try:
        o1, i1 = asyn.reset(seed=seed)
        o2, i2 = sync.reset(seed=seed)
        np.testing.assert_array_equal(o1, o2)
        for actions in _actions(30, n, seed=1):
            o1, r1, te1, tr1, i1 = asyn.step(actions)
            o2, r2, te2, tr2, i2 = sync.step(actions)
            np.testing.assert_array_equal(o1, o2)
            np.testing.assert_array_equal(r1, r2)
            np.testing.assert_array_equal(te1, te2)
            np.testing.assert_array_equal(tr1, tr2)
            for key in ("object_pose", "deformation", "constraint_error", "setpoint", "goal"):
                np.testing.assert_array_equal(i1[key], i2[key], err_msg=key)
    finally:
        asyn.close()
        sync.close()


# ------------------------------------------------------------------ no leaks through reset
def _assert_same_episode(a, b):
    """Everything observable of two episodes (:func:`conftest.run_rollout`) is the same: per
    step obs, reward, flags, info arrays, the full physics state (incl. the PID integrals) and
    the hand parameters."""
    assert len(a) == len(b)
    for s1, s2 in zip(a, b, strict=True):
        np.testing.assert_array_equal(s1.obs, s2.obs)
        np.testing.assert_array_equal(s1.state, s2.state)
        assert (s1.reward, s1.terminated) == (s2.reward, s2.terminated)
        assert s1.params == s2.params
        assert sorted(s1.info) == sorted(s2.info)
        for key in s1.info:
            np.testing.assert_array_equal(s1.info[key], s2.info[key], err_msg=key)


@pytest.mark.parametrize("randomize", [False, True])
def test_reset_with_a_seed_forgets_every_earlier_episode(randomize, make_env, rollout):
    kw = {**KW, "randomize": randomize, "reset_noise_deg": 1.0 if randomize else 0.0}
    acts_a = _actions(30, seed=2)
    acts_b = np.concatenate([_actions(10, seed=3), np.ones((40, 2), np.float32)])
    env = make_env(POSE, **kw)
    first = rollout(env, 1, acts_a)
    other = rollout(env, 2, acts_b)  # ends by squeezing until over-compressed
    assert other[-1].terminated and other[-1].info["termination_reason"] == "overcompressed"
    rollout(env, 3, _actions(5, seed=4))  # and a short one, cut mid-episode
    again = rollout(env, 1, acts_a)
    fresh = rollout(make_env(POSE, **kw), 1, acts_a)
    _assert_same_episode(first, fresh)
    _assert_same_episode(again, fresh)
    if randomize:  # the seed really drives the parameters
        assert other[0].params != first[0].params


def test_native_vector_env_reset_forgets_and_envs_do_not_interact():
    n, seed = 3, 30
    envs = SoftHandVectorEnv(num_envs=n, task="pose", max_episode_steps=8, **KW)
    acts = _actions(20, n, seed=5)
    acts[3:9, 0] = 1.0  # env 0 squeezes until it fails and restarts

    def run(venv, actions, s):
        out = [venv.reset(seed=s)[0]]
        for a in actions:
            o, r, te, tr, _ = venv.step(a)
            out += [o, r, te, tr]
        return out

    first = run(envs, acts, seed)
    run(envs, _actions(15, n, seed=6), seed + 100)  # other episodes in between
    again = run(envs, acts, seed)
    for x, y in zip(first, again, strict=True):
        np.testing.assert_array_equal(x, y)
    # env 1 of the batch = a batch of one seeded seed + 1: the other rows do not leak in
    alone = run(SoftHandVectorEnv(num_envs=1, task="pose", max_episode_steps=8, **KW),
                acts[:, 1:2], seed + 1)
    for x, y in zip(first, alone, strict=True):
        np.testing.assert_array_equal(np.asarray(x)[1:2], y)
