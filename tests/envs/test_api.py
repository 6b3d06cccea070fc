"""Single-environment API: registration, checkers, manual vs signature, seeding, actions, info."""

from __future__ import annotations

import ast
import inspect
import math
import pickle
import re
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import softhand_env
from softhand_env.envs import (
    ENV_IDS,
    RANDOM_KWARGS,
    V0_IDS,
    V1_HAND_OVERRIDES,
    V1_IDS,
    V1_KWARGS,
    V1_RANDOM_KWARGS,
    SoftHandEnv,
)
from softhand_env.envs.tasks import GOAL_TERMS, make_task
from softhand_env.physics.failure import REASONS
from softhand_env.physics.model import DN_1, DN_2, TH_OBJ, X_OBJ, initial_state
from softhand_env.physics.params import load_hand_params

ROOT = Path(softhand_env.__file__).resolve().parent
IDS = list(ENV_IDS)
GOAL_IDS = [i for i in IDS if ENV_IDS[i] != "none"]
REQUIRED_INFO = ("object_pose", "deformation", "constraint_error", "grasped", "is_success")


def assert_same(a, b):
    for s1, s2 in zip(a, b, strict=True):
        np.testing.assert_array_equal(s1.obs, s2.obs)
        np.testing.assert_array_equal(s1.info["object_pose"], s2.info["object_pose"])
        assert (s1.reward, s1.terminated, s1.truncated) == (s2.reward, s2.terminated,
                                                            s2.truncated)


# ------------------------------------------------------------------------------ registration
def test_ids_registered_with_time_limit_and_vector_entry_point():
    for env_id, task in ENV_IDS.items():
        spec = gym.spec(env_id)
        cfg = yaml.safe_load((ROOT / "configs" / "tasks" / f"{task}.yaml").read_text())
        assert spec.max_episode_steps == cfg["max_episode_steps"] > 0
        random = env_id[:-3].endswith("Random")
        extra = RANDOM_KWARGS if random else {}
        if env_id in V1_IDS:
            hand = {**extra.get("hand_overrides", {}), **V1_HAND_OVERRIDES}
            extra = {**extra, **V1_KWARGS, "hand_overrides": hand,
                     **(V1_RANDOM_KWARGS if random else {})}
        assert spec.kwargs == {"task": task, **extra}
        if env_id in V1_IDS:
            assert spec.kwargs["hand_overrides"]["integrator"] == "ros2"
            assert spec.kwargs["substep_limits"] and spec.kwargs["slip_window_ms"] == 20.0
        assert spec.vector_entry_point is not None
        env = gym.make(env_id)
        assert isinstance(env.unwrapped, SoftHandEnv)
        assert env.unwrapped.task.name == task
        env.close()


def _run(code: str) -> str:
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
        cwd=ROOT.parent,
    )
    assert res.returncode == 0, res.stderr
    return res.stdout


def test_import_registers_without_loading_physics():
    out = _run(
        "import sys, gymnasium as gym\n"
        "assert 'SoftHand-v0' not in gym.registry\n"
        "import softhand_env\n"
        "ids = ['SoftHand-v0', 'SoftHandReorient-v0', 'SoftHandTranslate-v0', 'SoftHandPose-v0']\n"
        "assert all(i in gym.registry for i in ids)\n"
        "print('numba' in sys.modules)\n"
    )
    assert out.strip() == "False"


def test_module_prefixed_make_and_lazy_rendering():
    # gym.make("softhand_env:...") imports the package, which registers the ids; rgb_array
    # rendering works headless without importing pygame
    out = _run(
        "import sys, gymnasium as gym\n"
        "env = gym.make('softhand_env:SoftHand-v0', render_mode='rgb_array')\n"
        "env.reset(seed=0)\n"
        "frame = env.render()\n"
        "print(frame.shape, frame.dtype, 'pygame' in sys.modules)\n"
    )
    assert out.strip() == "(480, 480, 3) uint8 False"


# ------------------------------------------------------------------------------ checkers
@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("obs_mode", ["proprio", "proprio_tactile"])
def test_checkers_pass_without_warnings(env_id, obs_mode, monkeypatch):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")  # check_env also opens the human window

    env = gym.make(env_id, obs_mode=obs_mode)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped, warn=True)
    env.close()


def test_absolute_radian_actions_pass_gymnasium_checker():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("SoftHand-v0", action_mode="absolute", normalize_action=False)
    space = env.action_space
    np.testing.assert_allclose(space.low, np.radians([-30, -30]), rtol=1e-7)
    np.testing.assert_allclose(space.high, np.radians([30, 30]), rtol=1e-7)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # the only warning expected is Gymnasium's advice to normalise the action space
        warnings.filterwarnings("ignore", message=".*symmetric and normalized.*")
        check_env(env.unwrapped, skip_render_check=True)


# ------------------------------------------------------------------------ manual vs signature
def _arguments_table(doc: str) -> list[tuple[str, str, str]]:
    section = doc.split("## Arguments", 1)[1].split("## Version History", 1)[0]
    rows = re.findall(r"^\s*\| `(\w+)` \| ([^|]+) \| `?([^|`]+)`? \|", section, flags=re.M)
    return [(name, typ.strip(), default.strip()) for name, typ, default in rows]


def test_arguments_table_matches_signature():
    rows = _arguments_table(SoftHandEnv.__doc__)
    params = [p for p in inspect.signature(SoftHandEnv.__init__).parameters.values()][1:]
    assert [r[0] for r in rows] == [p.name for p in params]
    for (name, typ, default), p in zip(rows, params, strict=True):
        assert ast.literal_eval(default) == p.default, name
        assert typ.split()[0] in str(p.annotation), (name, typ, p.annotation)


def test_env_options_record_every_keyword_with_its_default():
    from dataclasses import fields

    from softhand_env.envs.options import EnvOptions

    params = [p for p in inspect.signature(SoftHandEnv.__init__).parameters.values()][1:]
    assert [(f.name, f.default) for f in fields(EnvOptions)] == [(p.name, p.default)
                                                                  for p in params]
    env = gym.make("SoftHandReorient-v0", hand_overrides={"Kp": 12.0}).unwrapped
    assert env.options.task == "reorient" and env.options.hand_overrides == {"Kp": 12.0}
    with pytest.raises(TypeError, match="colour"):
        EnvOptions(colour="red")


def test_v1_ids_mirror_the_v0_ids():
    assert list(V1_IDS) == [i.replace("-v0", "-v1") for i in V0_IDS]
    assert set(ENV_IDS) == set(V0_IDS) | set(V1_IDS)
    for v0, v1 in zip(V0_IDS, V1_IDS, strict=True):
        assert V0_IDS[v0] == V1_IDS[v1]
        assert gym.spec(v0).max_episode_steps == gym.spec(v1).max_episode_steps
        assert gym.spec(v0).reward_threshold == gym.spec(v1).reward_threshold
        assert gym.make(v0).unwrapped.options.sensor_model == "ideal"
        assert gym.make(v1).unwrapped.options.sensor_model == "realistic"
        # -v0 keeps its keywords (none of v1's); -v1 is -v0 plus exactly v1's keywords
        k0, k1 = gym.spec(v0).kwargs, gym.spec(v1).kwargs
        v1_only = {**V1_KWARGS, **(V1_RANDOM_KWARGS if "Random" in v0 else {})}
        assert not set(k0) & set(v1_only) and "integrator" not in k0.get("hand_overrides", {})
        hand = {**k0.get("hand_overrides", {}), **V1_HAND_OVERRIDES}
        assert k1 == {**k0, **v1_only, "hand_overrides": hand}


def test_manual_ids_table_matches_registry():
    rows = re.findall(r"^\s*\| `(\S+-v0)`\s*\| `(\w+)`\s*\|[^|]+\|\s*(\d+) \(",
                      SoftHandEnv.__doc__, flags=re.M)
    assert {r[0] for r in rows} == set(V0_IDS)
    for env_id, task, steps in rows:
        assert ENV_IDS[env_id] == task and gym.spec(env_id).max_episode_steps == int(steps)


def test_reward_threshold_is_registered_for_goal_tasks_only():
    assert gym.spec("SoftHand-v0").reward_threshold is None
    for env_id in GOAL_IDS:
        spec = gym.spec(env_id)
        task = gym.make(env_id).unwrapped.task
        assert spec.reward_threshold == spec.max_episode_steps * task.goal_weight > 0


def test_manual_has_gymnasium_sections_in_order():
    doc = SoftHandEnv.__doc__
    sections = ["Description", "Action Space", "Observation Space", "Rewards",
                "Starting State", "Episode End", "Arguments", "Version History"]
    positions = [doc.index(f"## {s}") for s in sections]
    assert positions == sorted(positions)
    assert "sensing and allowed" in doc


def test_task_configs_only_hold_constructor_keywords():
    names = set(inspect.signature(SoftHandEnv.__init__).parameters)
    for task in ENV_IDS.values():
        cfg = yaml.safe_load((ROOT / "configs" / "tasks" / f"{task}.yaml").read_text())
        assert set(cfg) - {"max_episode_steps"} <= names, task


def test_task_defaults_come_from_config_and_kwargs_override():
    env = gym.make("SoftHandReorient-v0").unwrapped
    target = env.task.targets[0]
    assert target.name == "theta"
    assert target.goal_range == pytest.approx(math.radians(15.0))
    env2 = gym.make("SoftHandReorient-v0", goal_theta_range_deg=5.0, failure_weight=3.0).unwrapped
    assert env2.task.targets[0].goal_range == pytest.approx(math.radians(5.0))
    assert env2.task.failure_weight == 3.0
    with pytest.raises(ValueError, match="goal_x_range_mm"):
        gym.make("SoftHandReorient-v0", goal_x_range_mm=5.0)
    with pytest.raises(ValueError, match="does not use"):
        gym.make("SoftHand-v0", goal_weight=1.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"task": "juggle"}, "unknown task"),
        ({"action_mode": "velocity"}, "action_mode"),
        ({"normalize_action": False}, "absolute"),
        ({"control_dt": 0.01234}, "control_dt"),
        ({"obs_mode": "vision"}, "obs_mode"),
        ({"history_len": 0}, "history_len"),
        ({"joint_range_deg": (10.0, -10.0)}, "joint_range_deg"),
        ({"rand_mass": 1.5}, "rand_mass"),
        ({"hand_overrides": {"M_obj": -1.0}}, "M_obj"),
        ({"render_mode": "ascii"}, "render_mode"),
    ],
)
def test_invalid_keywords_raise_clear_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SoftHandEnv(**kwargs)


# ------------------------------------------------------------------------------- seeding
@pytest.mark.parametrize("env_id", GOAL_IDS)
def test_same_seed_bit_identical_trajectories(env_id, make_env, rollout):
    kwargs = {"randomize": True, "reset_noise_deg": 0.5, "max_episode_steps": 15}
    actions = np.random.default_rng(1).uniform(-1, 1, (40, 2)).astype(np.float32)
    a = rollout(make_env(env_id, **kwargs), 7, actions, on_end="reset")
    b = rollout(make_env(env_id, **kwargs), 7, actions, on_end="reset")
    assert_same(a, b)
    # and the seed matters (goal, parameters and noise differ)
    c = rollout(make_env(env_id, **kwargs), 8, actions, on_end="reset")
    assert not np.array_equal(a[0].obs, c[0].obs)


def test_seed_controls_goal_and_goal_in_range():
    env = gym.make("SoftHandPose-v0").unwrapped
    goals = []
    for seed in range(20):
        _, info = env.reset(seed=seed)
        goals.append(info["goal"])
    goals = np.array(goals)
    assert np.all(np.abs(goals[:, 0]) <= 0.010) and np.all(np.abs(goals[:, 1]) <= math.radians(10))
    assert len(np.unique(goals[:, 0])) == 20
    _, info = env.reset(seed=3)
    np.testing.assert_array_equal(info["goal"], goals[3])


@pytest.mark.parametrize("env_id", ["SoftHandTranslate-v0", "SoftHandTranslateRandom-v1"])
def test_pickle_round_trip_continues_identically(env_id):
    env = gym.make(env_id, obs_mode="proprio_tactile", obs_noise=0.01)
    env.reset(seed=2)
    for _ in range(5):
        env.step(env.action_space.sample())
    clone = pickle.loads(pickle.dumps(env))
    actions = np.random.default_rng(3).uniform(-1, 1, (10, 2)).astype(np.float32)
    for a in actions:
        o1, r1, te1, tr1, i1 = env.step(a)
        o2, r2, te2, tr2, i2 = clone.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert (r1, te1, tr1) == (r2, te2, tr2)
        np.testing.assert_array_equal(i1["object_pose"], i2["object_pose"])


def test_observations_are_copies():
    env = gym.make("SoftHandReorient-v0", history_len=2)
    obs0, info0 = env.reset(seed=0)
    keep = obs0.copy()
    obs0[:] = 123.0
    info0["object_pose"][:] = 5.0
    obs1, _, _, _, info1 = env.step(np.zeros(2, np.float32))
    # history slot 1 of the new observation is the reset frame, unaffected by the mutation
    np.testing.assert_array_equal(obs1[8:16], keep[:8])
    assert np.all(np.abs(info1["object_pose"]) < 0.1)
    obs1_copy = obs1.copy()
    env.step(np.zeros(2, np.float32))
    np.testing.assert_array_equal(obs1, obs1_copy)


# --------------------------------------------------------------------------- start state
def test_grasp_phase_and_point_contact_start():
    params = load_hand_params("paper_ch5")
    env = gym.make("SoftHand-v0", grasp_duration=0).unwrapped
    _, info = env.reset(seed=0)
    np.testing.assert_array_equal(env.physics.get_state(), initial_state(params))
    assert info["grasped"] is False  # point contact: d_n = 0
    env = gym.make("SoftHand-v0").unwrapped
    _, info = env.reset(seed=0)
    # default grasp (6 deg, 6 deg) for 0.5 s: d_n about 7 mm, object held at x = theta = 0
    assert info["grasped"] is True
    assert 0.005 < info["deformation"][0] < 0.009
    assert info["deformation"][0] == pytest.approx(info["deformation"][1], abs=1e-9)
    assert abs(info["object_pose"][0]) < 1e-9 and abs(info["object_pose"][2]) < 1e-9
    np.testing.assert_allclose(info["setpoint"], np.radians([6.0, 6.0]))
    # cached: a second reset gives the very same state
    y0 = env.physics.get_state()
    env.reset(seed=1)
    np.testing.assert_array_equal(env.physics.get_state(), y0)


def test_randomisation_changes_parameters_within_ranges():
    env = gym.make("SoftHand-v0", randomize=True).unwrapped
    base = load_hand_params("paper_ch5")
    masses, widths = set(), set()
    for seed in range(6):
        _, info = env.reset(seed=seed)
        p = env.physics.params
        assert abs(p.M_obj / base.M_obj - 1) <= 0.2 and abs(p.W_obj / base.W_obj - 1) <= 0.03
        assert abs(p.Kp / base.Kp - 1) <= 0.1 and p.Kd / base.Kd == pytest.approx(p.Kp / base.Kp)
        assert info["grasped"]
        masses.add(p.M_obj)
        widths.add(p.W_obj)
    assert len(masses) == 6 and len(widths) == 6
    plain = gym.make("SoftHand-v0").unwrapped
    plain.reset(seed=0)
    assert plain.physics.params == base


def test_control_period_and_render_fps():
    env = gym.make("SoftHand-v0", control_dt=0.01)
    assert env.unwrapped.dt == pytest.approx(0.01)
    assert env.unwrapped.config.n_substeps == 100
    assert env.metadata["render_fps"] == pytest.approx(100.0)
    assert gym.make("SoftHand-v0").unwrapped.dt == pytest.approx(0.02)


# ------------------------------------------------------------------------------- actions
def test_delta_actions_move_setpoints_and_are_clipped():
    env = gym.make("SoftHand-v0", max_delta_deg=2.0).unwrapped
    _, info0 = env.reset(seed=0)
    u0 = info0["setpoint"]
    _, _, _, _, info = env.step(np.array([1.0, -0.5], dtype=np.float32))
    np.testing.assert_allclose(info["setpoint"] - u0, np.radians([2.0, -1.0]), atol=1e-12)
    _, _, _, _, info2 = env.step(np.array([7.0, -9.0]))  # clipped to [-1, 1]
    np.testing.assert_allclose(info2["setpoint"] - info["setpoint"], np.radians([2.0, -2.0]),
                               atol=1e-12)


def test_absolute_actions_map_to_joint_range_and_clip():
    env = gym.make("SoftHand-v0", action_mode="absolute", joint_range_deg=(-20.0, 40.0)).unwrapped
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([0.0, 1.0], dtype=np.float32))
    np.testing.assert_allclose(info["setpoint"], np.radians([10.0, 40.0]), atol=1e-12)
    raw = gym.make("SoftHand-v0", action_mode="absolute", normalize_action=False).unwrapped
    raw.reset(seed=0)
    _, _, _, _, info = raw.step(np.array([0.05, 2.0]))
    np.testing.assert_array_equal(info["setpoint"], [0.05, math.radians(30.0)])


@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf], [-np.inf, 1.0]])
def test_nonfinite_actions_raise_and_leave_state(bad):
    env = gym.make("SoftHandReorient-v0").unwrapped
    env.reset(seed=0)
    y = env.physics.get_state()
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array(bad, dtype=np.float32))
    np.testing.assert_array_equal(env.physics.get_state(), y)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, dtype=np.float32))


# -------------------------------------------------------------------- rewards, info, ends
@pytest.mark.parametrize("env_id", IDS)
def test_info_keys_and_reward_is_sum_of_terms(env_id):
    env = gym.make(env_id)
    terms = GOAL_TERMS if env_id in GOAL_IDS else ()
    _, info = env.reset(seed=0)
    for key in REQUIRED_INFO + terms:
        assert key in info, key
    assert all(info[t] == 0.0 for t in terms)
    assert info["termination_reason"] is None
    rng = np.random.default_rng(0)
    for _ in range(30):
        _, reward, terminated, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        for key in REQUIRED_INFO + terms:
            assert key in info, key
        assert info["object_pose"].shape == (3,) and info["deformation"].shape == (4,)
        assert info["constraint_error"].shape == (2,)
        assert isinstance(info["grasped"], bool) and isinstance(info["is_success"], bool)
        assert reward == sum(info[t] for t in terms)
        if env_id not in GOAL_IDS:
            assert reward == 0.0
        if terminated:
            assert info["termination_reason"] in REASONS
            env.reset()
        else:
            assert info["termination_reason"] is None  # in every info, None while running


def test_reward_terms_follow_their_formulas():
    env = gym.make("SoftHandTranslate-v0", ctrl_weight=0.5, max_delta_deg=1.0).unwrapped
    env.reset(seed=4, options={"goal": [0.01]})
    goal = env.goal[0]
    assert goal == 0.01
    _, reward, _, _, info = env.step(np.array([0.4, -0.2], dtype=np.float32))
    x = info["object_pose"][0]
    assert info["reward_goal"] == pytest.approx(math.exp(-abs(x - goal) / 0.005), rel=1e-12)
    assert info["reward_ctrl"] == pytest.approx(-0.5 * (0.4**2 + 0.2**2), rel=1e-6)
    assert info["reward_failure"] == 0.0 and info["reward_success"] == 0.0
    assert not info["is_success"] and abs(x - goal) > 0.002  # x is near 0, x* = 10 mm


def test_success_when_goal_is_the_current_pose():
    env = gym.make("SoftHandPose-v0", terminate_on_success=True).unwrapped
    _, info = env.reset(seed=0, options={"goal": [0.0, 0.0]})
    assert info["is_success"]
    _, reward, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["is_success"] and terminated and info["termination_reason"] == "success"
    assert info["reward_success"] == 1.0 and reward == pytest.approx(1.0 + info["reward_goal"])


@pytest.mark.parametrize(
    "setpoint_deg, reason", [((-30.0, -30.0), "grasp_lost"), ((20.0, 20.0), "overcompressed")]
)
def test_physical_failures_terminate_with_reason(setpoint_deg, reason):
    env = gym.make("SoftHandReorient-v0", action_mode="absolute", normalize_action=False)
    env.reset(seed=0)
    for _ in range(20):
        obs, reward, terminated, truncated, info = env.step(np.radians(setpoint_deg))
        assert np.isfinite(obs).all() and np.isfinite(reward)
        if terminated:
            break
    assert terminated and not truncated
    assert info["termination_reason"] == reason
    assert info["reward_failure"] == -10.0
    dn = info["deformation"][:2]
    if reason == "overcompressed":
        assert dn.max() >= 0.5 * 0.020  # a/2 of Table 5.1
    else:
        assert dn.min() <= 0.0 and not info["grasped"]


def test_nonfinite_state_rolls_back_and_terminates(monkeypatch):
    from softhand_env.physics import hand, kernel

    env = gym.make("SoftHandReorient-v0").unwrapped
    env.reset(seed=0)
    before = env.physics.get_state()

    def poisoned(SRC, Y, U, PRM, TIME, n, ros2, H, ch_limit, dn_limit, base_limit, FLAGS, DIAG,
                 FAILED, GRASPED, REASON):
        # the real kernel, then what a blown-up integration leaves behind, then the real
        # rollback and classification
        U[:] = SRC
        y_prev = Y.copy()
        FLAGS[:] = 0
        kernel.advance_batch(Y, U, PRM, n, ch_limit, DIAG, FLAGS)
        Y[:] = np.nan
        FLAGS[:] = kernel.FLAG_NONFINITE
        DIAG[:, 1] = np.nan
        hand._finish_step(FLAGS, Y, y_prev, PRM, DIAG, TIME, ch_limit, dn_limit, base_limit,
                          FAILED, GRASPED, REASON)
        return True

    monkeypatch.setattr(hand, "_step_on_this_thread", poisoned)
    # the Python-dispatched pieces, where the kernel can be replaced (the one compiled call of
    # a single episode, envs/fused.py, binds the same _finish_step at compile time)
    monkeypatch.setattr(env._batch, "_fused", False)
    obs, reward, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and info["termination_reason"] == "nonfinite_state"
    assert np.isfinite(obs).all() and np.isfinite(reward)
    for key, value in info.items():
        if isinstance(value, (float, np.ndarray)):
            assert not np.isnan(value).any(), key
    np.testing.assert_array_equal(env.physics.get_state(), before)


@pytest.mark.parametrize("fused", [True, False])
def test_an_integration_that_overflows_rolls_back_and_terminates(fused, monkeypatch):
    """A real blow-up, not a replaced kernel: momenta of 1e200 overflow within the first
    substep; the one compiled call of a single episode and the Python-dispatched pieces both
    roll the state back and end the episode as nonfinite_state with finite outputs."""
    env = gym.make("SoftHandReorient-v0").unwrapped
    env.reset(seed=0)
    assert env._batch._fused  # the single episode's default path
    monkeypatch.setattr(env._batch, "_fused", fused)
    state = env.physics.get_state()
    state[9:18] = 1e200  # momenta p (9) of [q, p, z]
    env.physics.set_state(state)
    obs, reward, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and info["termination_reason"] == "nonfinite_state"
    assert np.isfinite(obs).all() and np.isfinite(reward)
    np.testing.assert_array_equal(env.physics.get_state(), state)


def test_time_limit_truncates():
    env = gym.make("SoftHand-v0", max_episode_steps=3)
    env.reset(seed=0)
    ends = [env.step(np.zeros(2, np.float32))[2:4] for _ in range(3)]
    assert ends == [(False, False), (False, False), (False, True)]


def test_paper_motion_keeps_deformation_in_validity_range():
    # sanity of the termination thresholds: the paper's first motion is not a failure
    env = gym.make("SoftHand-v0", action_mode="absolute", normalize_action=False,
                   grasp_duration=0).unwrapped
    env.reset(seed=0)
    for _ in range(50):
        _, _, terminated, _, info = env.step(np.radians([6.0, 6.0]))
        assert not terminated
    y = env.physics.get_state()
    assert 0 < y[DN_1] < 0.01 and 0 < y[DN_2] < 0.01
    assert abs(y[X_OBJ]) < 1e-6 and abs(y[TH_OBJ]) < 1e-6


def test_failing_grasp_raises_when_fixed_and_is_redrawn_when_randomised(monkeypatch):
    from softhand_env.envs import start
    from softhand_env.physics import PhysicsError

    # squeezing 12 deg per finger compresses the fingertips past a/2 during the grasp phase
    with pytest.raises(PhysicsError, match="grasp phase"):
        gym.make("SoftHand-v0", grasp_setpoint_deg=(12.0, 12.0)).reset(seed=0)
    # wide object-width randomisation: some draws over-compress; they are redrawn
    calls = []
    real = start.grasp_state
    monkeypatch.setattr(start, "grasp_state", lambda *a, **k: calls.append(1) or real(*a, **k))
    env = gym.make("SoftHand-v0", rand_width=0.2).unwrapped
    for seed in range(15):
        _, info = env.reset(seed=seed)
        assert info["grasped"] and info["deformation"][:2].max() < 0.01
    assert len(calls) > 15  # at least one draw was rejected and redrawn


# ------------------------------------------------------------------ untrusted actions and options
@pytest.mark.parametrize(
    "action",
    [
        np.array([1 + 1j, 0.0]),
        np.array(["a", "b"]),
        np.array([np.datetime64("2024-01-01")] * 2),
        np.ma.array([0.0, 0.0], mask=[True, False]),
        {"a": 1},
        [10**400, 0],
    ],
    ids=["complex", "str", "datetime", "masked", "dict", "huge-int"],
)
def test_non_real_actions_raise_type_error_naming_action(action):
    env = gym.make("SoftHandReorient-v0")
    env.reset(seed=0)
    with pytest.raises(TypeError, match="action"):
        env.step(action)


def test_real_actions_of_any_real_kind_are_accepted():
    env = gym.make("SoftHandReorient-v0")
    env.reset(seed=0)
    for action in (np.array([True, False]), np.array([0, 1], dtype=np.int8), [0.5, -0.5],
                   np.array([0.1, 0.2], dtype=np.float16)):
        env.step(action)


@pytest.mark.parametrize(
    "options,error,fragment",
    [
        ({"gaol": [0.0]}, ValueError, "unknown reset options \\['gaol'\\]; allowed: \\['goal'\\]"),
        ("goal", TypeError, "reset options must be a dict"),
        ({"goal": [1e300]}, ValueError, "outside the task's range"),
        ({"goal": ["x"]}, ValueError, "finite numbers"),
        ({"goal": [0.0, 0.0]}, ValueError, "1 finite numbers"),
    ],
)
def test_reset_options_are_checked(options, error, fragment):
    env = gym.make("SoftHandTranslate-v0")
    with pytest.raises(error, match=fragment):
        env.reset(seed=0, options=options)
    # a goal at the edge of the range is accepted
    _, info = env.reset(seed=0, options={"goal": [env.unwrapped.task.targets[0].goal_range]})
    assert info["goal"][0] == env.unwrapped.task.targets[0].goal_range


@pytest.mark.parametrize(
    "kwargs,fragment",
    [
        ({"history_len": 10**7}, "history_len must be in \\[1, 100\\]"),
        ({"control_dt": 1e12}, "control_dt must be a number in \\[0, 1\\]"),
        ({"grasp_duration": 1e300}, "grasp_duration must be a number in \\[0, 10\\]"),
        ({"hand_overrides": {"dt": 1e-300}}, "substeps per control step is more than"),
        ({"hand_overrides": {"dt": 1e-7}, "control_dt": 1e-3, "grasp_duration": 0.5},
         "grasp_duration / dt"),
        ({"max_delta_deg": 1e-200}, "max_delta_deg must be a number in \\[0.001, 30\\]"),
        ({"goal_weight": 1e300}, "goal_weight must be a number in \\[0, 1e\\+06\\]"),
        ({"ctrl_weight": 1e7}, "ctrl_weight"),
        ({"goal_theta_range_deg": 1e9}, "goal_theta_range_deg must be a number in \\(0, 90\\]"),
        ({"render_width": 10**6}, "render_width must be an int in \\[16, 4096\\]"),
        ({"obs_noise": 1e300}, "obs_noise"),
        ({"ch_limit": 1e300}, "ch_limit"),
    ],
)
def test_keywords_have_finite_ranges_checked_before_anything_runs(kwargs, fragment):
    with pytest.raises(ValueError, match=fragment):
        gym.make("SoftHandReorient-v0", **kwargs)


def test_reward_is_finite_at_the_edges_of_the_ranges():
    weights = {k: 1e6 for k in ("goal_weight", "success_weight", "ctrl_weight",
                                "failure_weight")}
    env = gym.make("SoftHandReorient-v0", action_mode="absolute", max_delta_deg=1e-3,
                   joint_range_deg=(-89.0, 89.0), **weights)
    env.reset(seed=0)
    for action in ([1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]):
        _, reward, terminated, _, info = env.step(np.array(action, dtype=np.float32))
        assert math.isfinite(reward) and all(math.isfinite(info[t]) for t in GOAL_TERMS)
        if terminated:
            env.reset()


def test_a_failed_step_is_never_a_success():
    """Success needs the object on the goal AND a step that did not fail: an episode that
    ends over-compressed (or slipping) with the object within tolerance does not count."""
    from softhand_env.envs.tasks import make_task

    task = make_task("pose")
    pose = (0.001, 0.075, 0.01)
    goal = (0.001, 0.01)
    ok = task.evaluate(pose, goal, 0.0, np.bool_(False), np.bool_(True))[1]
    failed = task.evaluate(pose, goal, 0.0, np.bool_(True), np.bool_(True))[1]
    assert ok and not failed
    batch = task.evaluate(tuple(np.full(3, v) for v in pose), goal, np.zeros(3),
                          np.array([False, True, False]), np.array([True, True, False]))[1]
    np.testing.assert_array_equal(batch, [True, False, False])


def test_goal_task_terms_follow_the_reward_formula_for_scalars_and_broadcast_batches():
    """evaluate (the compiled score_rows) against the module's formula: reward_goal =
    w exp(-sum |p - g| / scale), the success, control and failure terms; scalars give
    Python floats and a bool, arrays the arguments' broadcast shape."""
    from softhand_env.envs.tasks import make_task

    task = make_task("pose")
    (tx, tt) = task.targets
    rng = np.random.default_rng(5)
    x = rng.uniform(-2e-3, 2e-3, (3, 4))
    th = rng.uniform(-0.03, 0.03, (3, 4))
    goal = (rng.uniform(-2e-3, 2e-3, (1, 4)), 0.01)
    ctrl = rng.uniform(0, 1, (3, 1))
    failed = rng.uniform(size=(3, 4)) < 0.2
    grasped = np.array(True)
    (r_goal, r_success, r_ctrl, r_failure), success = task.evaluate(
        (x, 0.075, th), goal, ctrl, failed, grasped)
    dx, dth = np.abs(x - goal[0]), np.abs(th - goal[1])
    within = (dx <= tx.tolerance) & (dth <= tt.tolerance) & ~failed
    assert r_goal.shape == success.shape == (3, 4)
    expected = task.goal_weight * np.exp(-(dx / tx.scale + dth / tt.scale))
    np.testing.assert_allclose(r_goal, expected, rtol=1e-15)
    np.testing.assert_array_equal(success, within)
    np.testing.assert_array_equal(r_success, task.success_weight * within)
    np.testing.assert_array_equal(r_ctrl, np.broadcast_to(-task.ctrl_weight * ctrl, (3, 4)))
    np.testing.assert_array_equal(r_failure, -task.failure_weight * failed)
    terms, ok = task.evaluate((0.001, 0.075, 0.01), (0.001, 0.0105), 0.25, False, True)
    assert all(type(t) is float for t in terms) and ok is True
    assert math.isclose(terms[0], task.goal_weight * math.exp(-0.0005 / tt.scale),
                        rel_tol=1e-15)
    with pytest.raises(ValueError, match="goal must have 2 coordinates"):
        task.evaluate((0.0, 0.075, 0.0), (0.0,), 0.0, False, True)
    with pytest.raises(AttributeError):
        task.goal_weight = 2.0  # type: ignore[misc]


def test_version_history_lists_every_semantic_change():
    """The Version History names every semantic change of the ids: slip termination
    on by default, ``is_success`` False on a failed step, and v1 with each of its keywords
    (:data:`V1_KWARGS`, :data:`V1_HAND_OVERRIDES`, :data:`V1_RANDOM_KWARGS`)."""
    history = SoftHandEnv.__doc__.split("## Version History", 1)[1]
    history = " ".join(history.split())
    assert "terminate_on_slip=True`` by default" in history
    assert "``is_success`` is False on a failed step" in history
    v1 = history[history.index("- v1:"):]

    def shown(value):
        return f'"{value}"' if isinstance(value, str) else (
            f"{value:g}" if isinstance(value, float) else str(value))

    for key, value in {**V1_KWARGS, **V1_RANDOM_KWARGS}.items():
        assert f"{key}={shown(value)}" in v1, (key, value)
    for key, value in V1_HAND_OVERRIDES.items():
        assert f'hand_overrides={{"{key}": {shown(value)}}}' in v1, (key, value)
    assert "``-v0`` ids keep the semantics above" in v1


@pytest.mark.parametrize("task", ["translate", "reorient", "pose"])
def test_goal_draws_are_those_of_numpy_uniform(task):
    """The goal sampler reproduces ``rng.uniform(-range, range)`` bit for bit and leaves the
    generator where that call leaves it (goal sets drawn before stay the same goals)."""
    t = make_task(task)
    for scale in (1.0, 0.37):
        t.set_goal_scale(scale)
        a, b = np.random.default_rng(7), np.random.default_rng(7)
        for _ in range(2000):
            ranges = t._ranges * scale
            np.testing.assert_array_equal(t.sample_goal(a), b.uniform(-ranges, ranges))
        assert a.random() == b.random()
