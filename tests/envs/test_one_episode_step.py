"""The single environment's step (one compiled call, Python scalars) against the batched
pieces the vector env runs: the same observations, rewards, terminations and info, bit for
bit, over episodes that end in every way the configurations allow."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401

CASES = [
    ("SoftHandPose-v0", {}),
    ("SoftHandPose-v1", {}),  # realistic sensors, slip windows, ROS2
    ("SoftHandReorient-v0", {"obs_noise": 0.01, "history_len": 3,
                             "obs_mode": "proprio_tactile"}),
    ("SoftHandTranslate-v0", {"terminate_on_slip": False}),
    ("SoftHandTranslateRandom-v1", {"setpoint_latency": 0}),  # randomised, every sensor error
    ("SoftHandPoseRandom-v0", {}),  # set-point latency, observation noise
    ("SoftHandPoseRandom-v1", {"setpoint_latency": 3}),
    ("SoftHandPose-v0", {"terminate_on_success": True}),
    # a set-point ramp over a longer control step (pieces cut at the stairs), with latency
    ("SoftHandPoseRandom-v1", {"control_dt": 0.16, "max_delta_deg": 8.0,
                               "setpoint_ramp_ms": 80.0}),
    ("SoftHandPose-v1", {"control_dt": 0.05, "setpoint_ramp_ms": 30.0}),
]


def _run(env_id, kwargs, fused, actions):
    env = gym.make(env_id, max_episode_steps=30, **kwargs)
    base = env.unwrapped
    assert base._batch._fused  # the configuration steps one episode in one call
    base._batch._fused = fused
    # the first goal is the start pose: held there, the episode succeeds
    out = [env.reset(seed=5, options={"goal": np.zeros(base.task.goal_dim)})]
    for a in actions:
        step = env.step(a)
        out.append(step)
        if step[2] or step[3]:
            out.append(env.reset())
    env.close()
    return out


def _same(x, y, where):
    if isinstance(x, dict):
        assert sorted(x) == sorted(y), where
        for key in x:
            _same(x[key], y[key], f"{where}/{key}")
    elif isinstance(x, tuple):
        for k, (a, b) in enumerate(zip(x, y, strict=True)):
            _same(a, b, f"{where}[{k}]")
    elif isinstance(x, np.ndarray):
        assert x.dtype == y.dtype, where
        np.testing.assert_array_equal(x, y, err_msg=where)
    else:
        assert type(x) is type(y) and x == y, where


@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
def test_one_episode_step_equals_the_batched_pieces(env_id, kwargs):
    actions = np.random.default_rng(1).uniform(-1, 1, (90, 2)).astype(np.float32)
    actions[:3] = 0.0
    actions[10:25] = -1.0  # open the fingers: the grasp is lost, the episode fails
    actions[40:60] = 1.0  # squeeze: over-compression or slip where the checks allow
    fused = _run(env_id, kwargs, True, actions)
    batched = _run(env_id, kwargs, False, actions)
    assert len(fused) == len(batched)
    reasons = set()
    for k, (a, b) in enumerate(zip(fused, batched, strict=True)):
        _same(a, b, f"{env_id} item {k}")
        reasons.add(a[-1].get("termination_reason"))
    # episodes ended on their own (not only truncations), with success where it terminates
    assert len(reasons) >= 3
    assert ("success" in reasons) == kwargs.get("terminate_on_success", False)
