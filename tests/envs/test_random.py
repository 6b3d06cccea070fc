"""The randomisation ladder's ids (SoftHand*Random-v0) and the set-point latency keyword."""

from __future__ import annotations

import itertools
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import softhand_env  # noqa: F401
from softhand_env.envs import ENV_IDS, RANDOM_KWARGS, SoftHandEnv
from softhand_env.envs.randomization import FIELDS
from softhand_env.envs.signature import env_signature
from softhand_env.envs.start import grasp_state
from softhand_env.physics.params import load_hand_params

RANDOM_IDS = [i for i in ENV_IDS if i.endswith("Random-v0")]


def test_random_ids_are_registered_with_the_ladder_keywords():
    assert RANDOM_IDS == ["SoftHandReorientRandom-v0", "SoftHandTranslateRandom-v0",
                          "SoftHandPoseRandom-v0"]
    for env_id in RANDOM_IDS:
        spec, nominal = gym.spec(env_id), gym.spec(env_id.replace("Random", ""))
        assert spec.kwargs == {**nominal.kwargs, **RANDOM_KWARGS}
        assert spec.max_episode_steps == nominal.max_episode_steps
        assert spec.reward_threshold == nominal.reward_threshold
    assert {k: RANDOM_KWARGS[k] for k in FIELDS if k != "rand_friction"} == {
        "rand_width": 0.1, "rand_mass": 0.5, "rand_inertia": 0.5, "rand_stiffness": 0.3,
        "rand_damping": 0.3, "rand_gains": 0.3,
    }
    env = gym.make("SoftHandReorientRandom-v0").unwrapped
    assert env.config.params.dt == 5e-5 and env.config.n_substeps == 400
    assert env.config.setpoint_latency == 1 and env.config.randomization.obs_noise == 0.01


@pytest.mark.parametrize("env_id", RANDOM_IDS)
def test_random_ids_pass_gymnasium_and_sb3_check_env(env_id):
    gym_check_env(gym.make(env_id).unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(env_id), warn=True)


@pytest.mark.parametrize("env_id", RANDOM_IDS)
def test_signature_distinguishes_random_ids(env_id):
    nominal = env_id.replace("Random", "")
    assert env_signature(gym.make(env_id))["env_id"] == env_id
    # constructed directly: the id follows the keywords
    direct = SoftHandEnv(task=ENV_IDS[env_id], **RANDOM_KWARGS)
    assert env_signature(direct)["env_id"] == env_id
    assert env_signature(SoftHandEnv(task=ENV_IDS[env_id]))["env_id"] == nominal


def _corners():
    """Hand parameters at every corner of the Random ids' parameter box."""
    base = load_hand_params("paper_ch5", **RANDOM_KWARGS["hand_overrides"])
    for signs in itertools.product((-1.0, 1.0), repeat=len(FIELDS)):
        changes = {}
        for sign, (key, fields) in zip(signs, FIELDS.items(), strict=True):
            for field in fields:
                changes[field] = getattr(base, field) * (1 + sign * RANDOM_KWARGS.get(key, 0.0))
        yield base.replace(**changes)


def test_post_grasp_deformation_stays_within_the_model_validity():
    """How the ranges are checked: the grasp phase at every corner of the parameter box (d_n
    is monotone in width and stiffness, the parameters that set it), and 200 randomised resets
    of the Random id, none of which needs a redraw; all d_n within (0, a/2), the fingertip
    model's limit (the env's over-compression termination)."""
    env = gym.make("SoftHandPoseRandom-v0").unwrapped
    cfg = env.config
    corner_dn = []
    for params in _corners():
        y, _, _ = grasp_state(params, cfg.grasp_setpoint, cfg.n_grasp, cfg.ch_limit,
                              cfg.dn_limit, use_cache=False, base_limit=cfg.base_limit)
        env.physics.reset_hand(0, y, cfg.grasp_setpoint, params)
        corner_dn.append(env.physics.deformation[:2])
    corner_dn = np.array(corner_dn)
    a = cfg.params.a
    # measured: 4.89 .. 9.70 mm at the corners (200 resets: 4.97 .. 9.44 mm)
    assert 0.2 * a < corner_dn.min() and corner_dn.max() < 0.5 * a

    draws = []
    import softhand_env.envs.start as start

    calls = []
    original = start.grasp_state

    def counting(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    start.grasp_state = counting
    try:
        for seed in range(200):
            _, info = env.reset(seed=seed)
            assert info["grasped"]
            draws.append(info["deformation"][:2])
    finally:
        start.grasp_state = original
    draws = np.array(draws)
    assert len(calls) == 200  # no draw failed its grasp phase (no redraws, no bias)
    assert corner_dn.min() <= draws.min() and draws.max() <= corner_dn.max()


def _rollout(make, n, steps, seed=5):
    rng = np.random.default_rng(0)
    out = []
    obs, info = make.reset(seed=seed)
    out.append(obs)
    for _ in range(steps):
        a = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        obs, reward, term, trunc, info = make.step(a if n > 1 else a[0])
        out += [obs, reward, term, trunc, info["setpoint"], info["object_pose"],
                info["setpoint_latency"]]
        if n == 1 and (term or trunc):
            out.append(make.reset()[0])
    return out


def test_latency_single_and_vector_env_agree_bit_for_bit():
    kw = {"setpoint_latency": 1, "max_episode_steps": 6}
    vec = gym.make_vec("SoftHandReorient-v0", num_envs=3,
                       vectorization_mode="vector_entry_point", **kw)
    sync = gym.make_vec("SoftHandReorient-v0", num_envs=3, vectorization_mode="sync", **kw)
    a, b = _rollout(vec, 3, 20), _rollout(sync, 3, 20)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    _, info = vec.reset(seed=5)
    assert set(info["setpoint_latency"].tolist()) <= {0, 1}


def test_setpoint_latency_is_in_every_info_of_the_single_and_the_vector_env():
    """The episode's latency travels in info like every other per-episode value: row i of
    the vector env's infos is single env i (seeded s + i), at resets and autoresets."""
    n, kw = 6, {"setpoint_latency": 1, "max_episode_steps": 3}
    vec = gym.make_vec("SoftHandReorient-v0", num_envs=n,
                       vectorization_mode="vector_entry_point", **kw)
    singles = [gym.make("SoftHandReorient-v0", **kw) for _ in range(n)]
    _, info = vec.reset(seed=3)
    rows = [env.reset(seed=3 + i)[1]["setpoint_latency"] for i, env in enumerate(singles)]
    assert info["setpoint_latency"].dtype == np.int64 and info["_setpoint_latency"].all()
    assert info["setpoint_latency"].tolist() == rows and all(type(r) is int for r in rows)
    seen = set(rows)
    pending = [False] * n
    for _ in range(8):  # NextStep autoreset: the step after an episode end resets
        _, _, term, trunc, info = vec.step(np.zeros((n, 2), np.float32))
        for i, env in enumerate(singles):
            if pending[i]:
                single = env.reset()[1]["setpoint_latency"]
            else:
                single = env.step(np.zeros(2, np.float32))[4]["setpoint_latency"]
            assert info["setpoint_latency"][i] == single
            seen.add(single)
        pending = list(term | trunc)
    assert seen == {0, 1}


def test_latency_delays_the_commanded_setpoints():
    env = gym.make("SoftHandReorient-v0", setpoint_latency=1).unwrapped
    grasp = np.radians([6.0, 6.0])
    step = math.radians(env.options.max_delta_deg)
    seen = set()
    for seed in range(12):
        _, info = env.reset(seed=seed)
        latency = info["setpoint_latency"]
        seen.add(latency)
        a0, a1 = np.array([0.5, -0.25], np.float32), np.array([-1.0, 1.0], np.float32)
        info0 = env.step(a0)[4]
        info1 = env.step(a1)[4]
        assert info0["setpoint_latency"] == info1["setpoint_latency"] == latency
        u0 = grasp + a0.astype(np.float64) * step
        u1 = u0 + a1.astype(np.float64) * step
        if latency == 0:
            np.testing.assert_allclose(info0["setpoint"], u0, rtol=1e-12)
            np.testing.assert_allclose(info1["setpoint"], u1, rtol=1e-12)
        else:  # one step late; the control cost is that of the commands
            np.testing.assert_allclose(info0["setpoint"], grasp, rtol=1e-12)
            np.testing.assert_allclose(info1["setpoint"], u0, rtol=1e-12)
        ctrl = env.task.ctrl_weight * float(np.sum(a1.astype(np.float64) ** 2))
        assert info1["reward_ctrl"] == pytest.approx(-ctrl, rel=1e-9)
    assert seen == {0, 1}


def test_latency_zero_keeps_todays_episodes():
    a = _rollout(gym.make("SoftHandReorient-v0", max_episode_steps=8), 1, 20)
    b = _rollout(gym.make("SoftHandReorient-v0", max_episode_steps=8, setpoint_latency=0), 1, 20)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


@pytest.mark.parametrize("bad", [-1, 11, 1.0, True, "1", None])
def test_latency_range_is_checked(bad):
    with pytest.raises(ValueError, match="setpoint_latency"):
        gym.make("SoftHandReorient-v0", setpoint_latency=bad)


def test_every_corner_of_the_random_ranges_is_rk4_stable():
    """With the stability check of the finger/PID modes (where the physics has it): every
    corner of the Random ids' box is stable at their 0.05 ms substep, not at 0.1 ms."""
    stability = pytest.importorskip("softhand_env.physics.stability")
    widths = {k: RANDOM_KWARGS[k] for k in FIELDS if k in RANDOM_KWARGS}
    groups = {k: FIELDS[k] for k in widths}
    base = load_hand_params("paper_ch5", **RANDOM_KWARGS["hand_overrides"])
    stability.check_randomization_ranges(base, groups, widths)
    with pytest.raises(ValueError, match="rand_"):
        stability.check_randomization_ranges(load_hand_params("paper_ch5"), groups, widths)


def test_delay_setpoints_applies_the_command_of_latency_steps_ago():
    """The compiled delay both step paths share, against a plain history of commands: with
    K = 3 and latencies 0..3 per row, step t applies the command of step t - L (the start
    set-points before the first command)."""
    from softhand_env.envs.actions import delay_setpoints

    k, latency = 3, np.array([0, 1, 2, 3])
    start = np.array([[0.1, -0.1]] * 4)
    sent = np.repeat(start[:, None], k, axis=1).copy()
    applied = np.empty((4, 2))
    history = []
    for t, cmd in enumerate(np.random.default_rng(0).normal(size=(9, 4, 2))):
        history.append(cmd)
        delay_setpoints(cmd, sent, latency, applied)
        for s, lag in enumerate(latency):
            want = history[t - lag][s] if t >= lag else start[s]
            np.testing.assert_array_equal(applied[s], want)
        newest = np.array(history[::-1][:k]).transpose(1, 0, 2)  # (4, <=k, 2), newest first
        np.testing.assert_array_equal(sent[:, : newest.shape[1]], newest)
