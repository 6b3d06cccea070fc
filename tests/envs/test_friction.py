"""Friction, contact tension and stability checks of the environments.

Every control step reports the contact impulses of the step, the friction ratio |J_t| / J_n and
tension per fingertip; a step above the hand's mu ends the episode with "slip", a pulling one
with "tension" (``terminate_on_slip``, default True). Randomisation ranges with an RK4-unstable
corner are refused at construction; ``rand_friction`` is drawn after the goal.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import SyncVectorEnv

import softhand_env  # noqa: F401  (registers the environments)
from agents.scripted import PaperSequencePolicy
from softhand_env.envs import SoftHandVectorEnv
from softhand_env.envs.signature import env_signature
from softhand_env.physics import HandPhysics

LOW_MU = {"mu": 0.2}


def test_contact_info_at_reset_and_step():
    env = gym.make("SoftHandReorient-v0")
    _, info = env.reset(seed=0)
    np.testing.assert_array_equal(info["friction_ratio"], [0.0, 0.0])
    np.testing.assert_array_equal(info["contact_impulse"], np.zeros(4))
    np.testing.assert_array_equal(info["tension"], [False, False])
    assert info["tension"].dtype == bool
    _, _, terminated, _, info = env.step(np.array([0.5, -0.5], dtype=np.float32))
    assert not terminated
    assert info["friction_ratio"].shape == (2,) and info["contact_impulse"].shape == (4,)
    assert np.all(info["contact_impulse"][:2] > 0) and not info["tension"].any()
    jn, jt = info["contact_impulse"][:2], info["contact_impulse"][2:]
    np.testing.assert_array_equal(info["friction_ratio"], np.abs(jt) / jn)


def test_contact_impulse_is_the_physics_impulse_of_the_control_step():
    """The env's impulse is that of the hand physics advanced alone from the same state with
    the same set-points over the control step (200 substeps)."""
    env = gym.make("SoftHandReorient-v0", action_mode="absolute", normalize_action=False)
    env.reset(seed=0)
    base = env.unwrapped
    physics = HandPhysics(base.config.params)
    physics.set_state(base.physics.get_state())
    u = np.radians([7.0, 5.0])
    _, _, _, _, info = env.step(u)
    status = physics.step(u, base.config.n_substeps)
    np.testing.assert_array_equal(info["contact_impulse"], status.impulse)
    np.testing.assert_array_equal(info["friction_ratio"], status.friction_ratio)


def _paper_replay(**kwargs):
    policy = PaperSequencePolicy(duration=1.0)
    env = gym.make("SoftHand-v0", max_episode_steps=policy.episode_steps,
                   **policy.env_kwargs, **kwargs)
    obs, _ = env.reset(seed=0)
    infos = []
    for k in range(policy.episode_steps):
        obs, _, terminated, truncated, info = env.step(policy.action(0, obs, k))
        infos.append(info)
        if terminated or truncated:
            break
    return infos, terminated


def test_terminate_on_slip_false_only_reports():
    """mu = 0.2: the replay slips at control step 52 (tests/agents/test_scripted.py); without
    slip termination it runs to the end and reports the ratios above mu."""
    infos, terminated = _paper_replay(hand_overrides=LOW_MU, terminate_on_slip=False)
    assert not terminated and len(infos) == 400
    assert all(info["termination_reason"] is None for info in infos)
    ratio = np.array([info["friction_ratio"] for info in infos])
    assert (ratio > 0.2).any(axis=1).sum() > 100 and ratio.max() < 0.6


def test_native_vector_env_slips_like_single_envs():
    """Bit for bit the same impulses, ratios and slip terminations as single environments."""
    policy = PaperSequencePolicy(duration=1.0)
    kwargs = {**policy.env_kwargs, "hand_overrides": LOW_MU,
              "max_episode_steps": policy.episode_steps}
    n = 2
    native = SoftHandVectorEnv(num_envs=n, task="none", **kwargs)
    single = SyncVectorEnv([lambda: gym.make("SoftHand-v0", **kwargs)] * n)
    o1, _ = native.reset(seed=3)
    o2, _ = single.reset(seed=3)
    slipped = 0
    for k in range(60):
        action = np.tile(policy.action(0, o1[0], k), (n, 1))
        o1, _, te1, _, i1 = native.step(action)
        o2, _, te2, _, i2 = single.step(action)
        np.testing.assert_array_equal(te1, te2)
        for key in ("friction_ratio", "contact_impulse", "tension"):
            np.testing.assert_array_equal(i1[key], i2[key], err_msg=key)
        for a, b, m in zip(i1["termination_reason"], i2["termination_reason"],
                           i1["_termination_reason"], strict=True):
            assert not m or a == b
        slipped += int(sum(r == "slip" for r in i1["termination_reason"]))
        if te1.all():
            break
    assert slipped == n
    native.close()
    single.close()


def test_rand_friction_is_drawn_after_the_goal():
    """rand_friction changes mu per episode (within +-20 %) and leaves the other parameters,
    the grasp and the goal of a seeded episode as they are without it."""
    with_f = gym.make("SoftHandPose-v0", randomize=True)
    without = gym.make("SoftHandPose-v0", randomize=True, rand_friction=0.0)
    mus = []
    for seed in range(5):
        with_f.reset(seed=seed)
        without.reset(seed=seed)
        p1, p2 = with_f.unwrapped.physics.params, without.unwrapped.physics.params
        assert p1.replace(mu=p2.mu) == p2
        np.testing.assert_array_equal(with_f.unwrapped.goal, without.unwrapped.goal)
        np.testing.assert_array_equal(
            with_f.unwrapped.physics.get_state(), without.unwrapped.physics.get_state()
        )
        assert p2.mu == 1.0
        mus.append(p1.mu)
    assert all(0.8 <= m <= 1.2 for m in mus) and len(set(mus)) == 5


def test_unstable_randomisation_ranges_are_refused_at_construction():
    with pytest.raises(ValueError, match=r"rand_gains \+0\.3.*finger joint.*<= 0\.0627"):
        gym.make("SoftHandReorient-v0", randomize=True, rand_gains=0.3)
    with pytest.raises(ValueError, match=r"rand_gains \+0\.5.*rand_gains <= 0\.374"):
        gym.make("SoftHandReorient-v0", rand_gains=0.5)
    gym.make("SoftHandReorient-v0", rand_gains=0.37)
    with pytest.raises(ValueError, match=r"rand_friction = 0\.2 draws mu up to 10\.8"):
        gym.make("SoftHandReorient-v0", hand_overrides={"mu": 9.0}, rand_friction=0.2)
    with pytest.raises(ValueError, match="terminate_on_slip"):
        gym.make("SoftHandReorient-v0", terminate_on_slip=1)


def test_unstable_hand_warns_at_construction():
    with pytest.warns(RuntimeWarning, match="finger joint"):
        gym.make("SoftHandReorient-v0", hand_overrides={"Kd": 28.0})


def test_signature_ignores_slip_termination():
    """Episode-end keywords are not part of the signature: models trained before slip
    termination existed still fit the environment."""
    a = env_signature(gym.make("SoftHandTranslate-v0"))
    b = env_signature(gym.make("SoftHandTranslate-v0", terminate_on_slip=False))
    assert a == b and "terminate_on_slip" not in a


def test_contact_validated_follows_the_validated_box():
    """info["contact_validated"] is the validated box of the contact model (d_n <= 0.4 a,
    |theta_p| <= 30 deg), computed from the state the info reports; same in the vector env."""
    import math

    env = gym.make("SoftHandReorient-v0", action_mode="absolute", normalize_action=False)
    _, info = env.reset(seed=0)
    assert info["contact_validated"].shape == (2,) and info["contact_validated"].all()
    # rotating both fingers far to one side tilts the contact angles beyond 30 deg
    seen_outside = False
    for _ in range(200):
        u = info["setpoint"] + np.radians([0.9, -0.9])
        _, _, term, trunc, info = env.step(u)
        q = env.unwrapped.physics
        th_obj = info["object_pose"][2]
        fa = q.finger_angles
        theta_p = np.array([fa[0] - th_obj, fa[1] + th_obj])
        expect = (info["deformation"][:2] <= 0.4 * q.params.a) & (
            np.abs(theta_p) <= math.radians(30.0))
        np.testing.assert_array_equal(info["contact_validated"], expect)
        seen_outside |= not info["contact_validated"].all()
        if term or trunc:
            break
    assert seen_outside
