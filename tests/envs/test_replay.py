"""Scripted replay of the paper's motions 1-8 through gym.make matches the simulate module."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import softhand_env  # noqa: F401
from softhand_env.physics.motions import PAPER_MOTIONS_DEG, run_paper_motions

STEPS_PER_MOTION = 50  # 1 s per motion at the default 20 ms control period


def test_replay_of_motions_1_to_8_matches_run_paper_motions():
    env = gym.make(
        "SoftHand-v0", action_mode="absolute", normalize_action=False, grasp_duration=0
    )
    assert env.unwrapped.dt == 0.02
    _, info = env.reset(seed=0)
    poses, t = [info["object_pose"]], [0.0]
    for setpoint in np.radians(PAPER_MOTIONS_DEG):
        for _ in range(STEPS_PER_MOTION):
            _, reward, terminated, truncated, info = env.step(setpoint)
            assert reward == 0.0 and not terminated and not truncated
            assert info["grasped"]
            poses.append(info["object_pose"])
            t.append(t[-1] + env.unwrapped.dt)
    poses = np.array(poses)

    ref = run_paper_motions()  # recorded every 1 ms
    idx = np.searchsorted(ref.t, np.array(t) - 1e-9)
    np.testing.assert_allclose(ref.t[idx], t, atol=1e-9)
    # both run the same compiled kernel with the same substeps (only the chunking per call
    # differs), so the poses agree to round-off; 1e-9 m / 1e-9 rad is the acceptance bound
    np.testing.assert_allclose(poses, ref.y[idx, :3], rtol=0, atol=1e-9)
    # the replay goes somewhere: the paper's motions move the object by tens of mm
    assert np.ptp(poses[:, 0]) > 0.03 and np.ptp(poses[:, 2]) > 0.4
