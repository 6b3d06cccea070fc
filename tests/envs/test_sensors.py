"""Sensor models: ``"ideal"`` reads the exact state (the ``-v0`` behaviour), ``"realistic"``
quantises and perturbs it as configured, from the env's seeded generator, the single env equal
to the vector env's rows, ``info`` unchanged."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import yaml

import softhand_env  # noqa: F401  (registers the environments)
from softhand_env.envs import SoftHandEnv, sensors
from softhand_env.envs.observation import ANGLE_SCALE, TORQUE_SCALE, VELOCITY_SCALE
from softhand_env.envs.sensors import RANGES, SensorSpec, SensorState, load_sensor_spec

SPEC = load_sensor_spec("realistic")
Q = math.radians(SPEC.encoder_resolution_deg)


def _actions(n, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, (n, 2)).astype(np.float32)


def _episode(env, seed, actions):
    """Observations, and the true joint angles / PID torques, of one episode (stops at its
    end)."""
    obs, info = env.reset(seed=seed)
    p = env.unwrapped.physics
    rows = [(obs, p.finger_angles.copy(), p.joint_torques.copy(), info)]
    for a in actions:
        obs, _, term, trunc, info = env.step(a)
        rows.append((obs, p.finger_angles.copy(), p.joint_torques.copy(), info))
        if term or trunc:
            break
    return rows


# ------------------------------------------------------------------------------ the YAML
def test_realistic_yaml_values_units_and_ranges(tmp_path, monkeypatch):
    raw = yaml.safe_load((sensors.SENSOR_CONFIG_DIR / "realistic.yaml").read_text())
    assert set(raw) == set(RANGES) == {f for f in SensorSpec.__dataclass_fields__} - {"name"}
    assert all(k.endswith(("_deg", "_nm", "_mm", "_tolerance")) for k in raw)
    assert SPEC.encoder_resolution_deg == 360 / 2**12
    assert SPEC.name == "realistic" and not SPEC.ideal and load_sensor_spec("ideal").ideal
    monkeypatch.setattr(sensors, "SENSOR_CONFIG_DIR", tmp_path)
    for edit, match in [({"torque_noise_nm": -0.1}, "torque_noise_nm must be a number in"),
                        ({"encoder_resolution_deg": 0.0}, r"in \(0, 10\]"),
                        ({"tactile_noise_mm": float("nan")}, "tactile_noise_mm"),
                        ({"colour": 1}, "unknown keys"), ({"torque_bias_nm": "0.1"}, "bias")]:
        (tmp_path / "realistic.yaml").write_text(yaml.safe_dump({**raw, **edit}))
        with pytest.raises(ValueError, match=match):
            load_sensor_spec("realistic")


def test_bad_sensor_keywords_raise():
    with pytest.raises(ValueError, match="sensor_model must be one of"):
        SoftHandEnv(sensor_model="perfect")
    with pytest.raises(ValueError, match="rand_sensors=True .* sensor_model='realistic'"):
        SoftHandEnv(rand_sensors=True)


# --------------------------------------------------------------------------------- ideal
@pytest.mark.parametrize("env_id", ["SoftHandPose-v0", "SoftHandPose-v1"])
def test_ideal_observes_the_exact_readouts_and_realistic_does_not(env_id):
    env = gym.make(env_id, obs_mode="proprio_tactile")
    base = env.unwrapped
    ideal = env_id.endswith("-v0")
    assert base.sensors.ideal == ideal and (base._batch.sensing is None) == ideal
    exact = []
    obs, _ = env.reset(seed=3)
    for a in _actions(20):
        frame = base.observation_from_state(base.physics.get_state(), base.physics.setpoint)
        exact.append(np.array_equal(obs[:12], frame))
        obs, *_ = env.step(a)
    assert all(exact) if ideal else not any(exact)


# ----------------------------------------------------------------------------- realistic
def test_encoder_angles_on_the_grid_and_velocity_their_difference():
    env = gym.make("SoftHandPose-v1")
    rows = _episode(env, 5, _actions(60))
    obs = np.array([r[0] for r in rows], dtype=np.float64)
    counts = obs[:, :2] * ANGLE_SCALE / Q
    # float32 rounding of a 0.5-scaled entry is ~1e-5 counts; off-grid values spread on 0..0.5
    assert np.abs(counts - np.round(counts)).max() < 1e-3
    velocity_counts = obs[1:, 2:4] * VELOCITY_SCALE * env.unwrapped.dt / Q
    np.testing.assert_allclose(velocity_counts, np.diff(np.round(counts), axis=0), atol=1e-3)
    assert np.all(obs[0, 2:4] == 0.0)  # no earlier reading at reset
    # the exact angles are not on the grid: the same check fails on the ideal env
    ideal = np.array([r[0] for r in _episode(gym.make("SoftHandPose-v0"), 5, _actions(60))])
    off = ideal[:, :2] * ANGLE_SCALE / Q
    assert np.mean(np.abs(off - np.round(off)) < 1e-3) < 0.05
    # and the angle reading is within noise + half a count of the true angle
    true = np.array([r[1] for r in rows])
    err = obs[:, :2] * ANGLE_SCALE - true
    assert np.abs(err).max() < Q / 2 + 6 * math.radians(SPEC.encoder_noise_deg)


def test_noise_statistics_match_the_configured_std():
    """SensorState on uniform true angles: the angle error is noise + a rounding error
    uniform on one count, independent of it (variance sigma^2 + q^2/12); torque and tactile
    errors minus the episode's offset are N(0, sigma^2). Tolerance: 5 standard errors of a
    sample std, sigma / sqrt(2 n)."""
    n_env, n_read = 50, 200
    state = SensorState(SPEC, n_env, 0.02, tactile=True, rand_gain=False)
    rngs = [np.random.default_rng(100 + i) for i in range(n_env)]
    for i in range(n_env):
        state.start(i, rngs[i])
    src = np.random.default_rng(0)
    ang_err, tau_err, tac_err = [], [], []
    for k in range(n_read):
        theta = src.uniform(-0.3, 0.3, (n_env, 2))
        tau = src.uniform(-5, 5, (n_env, 2))
        d = src.uniform(0, 0.01, (n_env, 4))
        a, _, t, dd = state.read(theta, tau, d, range(n_env), rngs, first=k == 0)
        ang_err.append(a - theta)
        tau_err.append(t - tau - state.torque_bias)
        tac_err.append(dd - d)
    n = n_env * n_read

    def check(err, sigma, count):
        std = float(np.std(err))
        assert abs(std - sigma) < 5 * sigma / math.sqrt(2 * count), (std, sigma)
        assert abs(float(np.mean(err))) < 5 * sigma / math.sqrt(count)

    check(np.array(ang_err), math.hypot(math.radians(SPEC.encoder_noise_deg), Q / math.sqrt(12)),
          2 * n)
    check(np.array(tau_err), SPEC.torque_noise_nm, 2 * n)
    check(np.array(tac_err), SPEC.tactile_noise_mm * 1e-3, 4 * n)
    bias = state.torque_bias.ravel()
    assert abs(np.std(bias) - SPEC.torque_bias_nm) < 5 * SPEC.torque_bias_nm / math.sqrt(
        2 * bias.size)


def test_torque_bias_constant_in_an_episode_and_drawn_per_episode():
    env = gym.make("SoftHandPose-v1")
    base = env.unwrapped
    biases = []
    for seed in range(3):
        rows = _episode(env, seed, np.zeros((150, 2), dtype=np.float32))
        assert len(rows) == 151
        cal = base.sensor_calibration
        np.testing.assert_array_equal(cal["torque_gain"], [1.0, 1.0])  # nominal: gain exact
        err = np.array([r[0][6:8] * TORQUE_SCALE - r[2] for r in rows], dtype=np.float64)
        se = SPEC.torque_noise_nm / math.sqrt(len(rows))
        # the error's mean is the episode's offset (float32 rounding of obs: < 1e-6 N m)
        assert np.all(np.abs(err.mean(axis=0) - cal["torque_bias_nm"]) < 5 * se)
        half = len(rows) // 2
        assert np.all(np.abs(err[:half].mean(axis=0) - err[half:].mean(axis=0)) < 7 * se)
        assert abs(np.std(err) - SPEC.torque_noise_nm) < 5 * SPEC.torque_noise_nm / math.sqrt(
            2 * err.size)
        biases.append(cal["torque_bias_nm"])
    assert len({tuple(b) for b in biases}) == 3
    env.reset(seed=1)
    np.testing.assert_array_equal(base.sensor_calibration["torque_bias_nm"], biases[1])


def test_random_v1_draws_the_torque_gain_per_episode():
    env = gym.make("SoftHandPoseRandom-v1")
    gains = []
    for seed in range(4):
        env.reset(seed=seed)
        gains.append(env.unwrapped.sensor_calibration["torque_gain"])
    gains = np.array(gains)
    tol = SPEC.torque_gain_tolerance
    assert np.all(np.abs(gains - 1.0) <= tol) and len(np.unique(gains)) == gains.size


def test_seeded_determinism_and_the_seed_matters():
    actions = _actions(30, seed=4)
    kw = {"obs_mode": "proprio_tactile", "history_len": 2}
    a = _episode(gym.make("SoftHandPoseRandom-v1", **kw), 9, actions)
    b = _episode(gym.make("SoftHandPoseRandom-v1", **kw), 9, actions)
    c = _episode(gym.make("SoftHandPoseRandom-v1", **kw), 10, actions)
    for ra, rb in zip(a, b, strict=True):
        np.testing.assert_array_equal(ra[0], rb[0])
    assert not np.array_equal(a[0][0], c[0][0])


@pytest.mark.parametrize("env_id", ["SoftHandPose-v1", "SoftHandPoseRandom-v1"])
def test_single_envs_equal_the_vector_env_rows(env_id):
    n, steps, seed = 3, 25, 21
    kw = {"obs_mode": "proprio_tactile", "history_len": 2}
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                        max_episode_steps=8, **kw)
    singles = [gym.make(env_id, max_episode_steps=8, **kw) for _ in range(n)]
    vobs, _ = venv.reset(seed=seed)
    sobs = np.stack([e.reset(seed=seed + i)[0] for i, e in enumerate(singles)])
    np.testing.assert_array_equal(vobs, sobs)
    done = np.zeros(n, dtype=bool)
    restarts = 0
    actions = np.random.default_rng(2).uniform(-1, 1, (steps, n, 2)).astype(np.float32)
    for act in actions:
        vobs, vrew, vterm, vtrunc, _ = venv.step(act)
        for i, env in enumerate(singles):
            if done[i]:  # NextStep autoreset: this step restarts env i
                o, _ = env.reset()
                r, te, tr = 0.0, False, False
                restarts += 1
            else:
                o, r, te, tr, _ = env.step(act[i])
            np.testing.assert_array_equal(vobs[i], o)
            assert (vrew[i], vterm[i], vtrunc[i]) == (r, te, tr)
            done[i] = te or tr
    assert restarts >= n  # every env ran into its time limit at least once


def test_info_keeps_the_true_values():
    """The same -v1 id with ideal and with realistic sensing, same seed and actions: the same
    physics, goals and info (the sensor draws come after every other draw), different
    observations."""
    actions = _actions(40, seed=6)
    keys = ("object_pose", "deformation", "setpoint", "goal", "friction_ratio", "is_success")
    for env_id in ("SoftHandPose", "SoftHandPoseRandom"):
        ideal = {"sensor_model": "ideal"}
        if env_id.endswith("Random"):
            ideal["rand_sensors"] = False
        v0 = _episode(gym.make(f"{env_id}-v1", obs_mode="proprio_tactile", **ideal), 2, actions)
        v1 = _episode(gym.make(f"{env_id}-v1", obs_mode="proprio_tactile"), 2, actions)
        assert len(v0) == len(v1)
        for r0, r1 in zip(v0, v1, strict=True):
            for key in keys:
                np.testing.assert_array_equal(r0[3][key], r1[3][key])
            np.testing.assert_array_equal(r0[1], r1[1])
            assert not np.array_equal(r0[0], r1[0])


@pytest.mark.parametrize("env_id", ["SoftHandPose-v1", "SoftHandPoseRandom-v1"])
def test_realistic_observation_stays_scaled(env_id):
    """The sensed frame keeps the observation's scaling: inside the observation space, each
    entry's error against the exact frame a small fraction of its O(1) scale (rms at most 0.06
    scaled units: the tangential deformation's 0.05 mm noise on its 1 mm scale is the largest),
    the set-point entries exact on the nominal id (no ``obs_noise`` there)."""
    env = gym.make(env_id, obs_mode="proprio_tactile")
    base = env.unwrapped
    errors = []
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        for a in _actions(60, seed):
            exact = base.observation_from_state(base.physics.get_state(), base.physics.setpoint)
            assert env.observation_space.contains(obs)
            errors.append(obs[:12] - exact)
            obs, _, term, trunc, _ = env.step(a)
            if term or trunc:
                break
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    assert np.all(rms < 0.06), rms
    assert np.all(rms[[0, 1, 6, 7]] > 0)  # angles and torques are sensed, not copied
    if "Random" not in env_id:
        np.testing.assert_array_equal(rms[4:6], 0.0)


# ---------------------------------------------------------------------- sensor_noise_scale
def test_sensor_noise_scale_scales_the_noise_and_offset_not_the_quantisation_or_gains():
    assert SPEC.scaled(1.0) == SPEC
    half = SPEC.scaled(0.5)
    assert half.encoder_noise_deg == 0.5 * SPEC.encoder_noise_deg > 0
    assert half.torque_noise_nm == 0.5 * SPEC.torque_noise_nm > 0
    assert half.torque_bias_nm == 0.5 * SPEC.torque_bias_nm > 0
    assert half.tactile_noise_mm == 0.5 * SPEC.tactile_noise_mm > 0
    assert half.encoder_resolution_deg == SPEC.encoder_resolution_deg
    assert half.torque_gain_tolerance == SPEC.torque_gain_tolerance
    assert half.name == "realistic"
    env = gym.make("SoftHandPoseRandom-v1", sensor_noise_scale=2.0)
    assert env.unwrapped.sensors == SPEC.scaled(2.0)
    assert env.unwrapped.options.sensor_noise_scale == 2.0
    # the registered ids keep their sensing
    assert gym.make("SoftHandPose-v1").unwrapped.sensors == SPEC


@pytest.mark.parametrize("bad", [-0.5, 10.5, float("nan"), float("inf")])
def test_sensor_noise_scale_range_is_checked(bad):
    with pytest.raises(ValueError, match=r"sensor_noise_scale must be a number in \[0, 10\]"):
        gym.make("SoftHandPose-v1", sensor_noise_scale=bad)


def test_sensor_noise_scale_needs_a_sensor_model():
    with pytest.raises(ValueError, match="sensor_noise_scale .* sensor_model='realistic'"):
        gym.make("SoftHandPose-v0", sensor_noise_scale=0.0)
    assert gym.make("SoftHandPose-v0", sensor_noise_scale=1.0).unwrapped.sensors.ideal


def test_sensor_noise_scale_changes_the_observation_not_the_physics():
    actions = _actions(15, seed=4)
    runs = {s: _episode(gym.make("SoftHandPose-v1", obs_mode="proprio_tactile",
                                 sensor_noise_scale=s), 21, actions)
            for s in (0.0, 1.0)}
    assert len(runs[0.0]) == len(runs[1.0]) > 5
    for (o0, th0, tau0, i0), (_o1, th1, tau1, i1) in zip(runs[0.0], runs[1.0], strict=True):
        # the same true state, info and goal ...
        np.testing.assert_array_equal(th0, th1)
        np.testing.assert_array_equal(tau0, tau1)
        np.testing.assert_array_equal(i0["object_pose"], i1["object_pose"])
        np.testing.assert_array_equal(i0["deformation"], i1["deformation"])
        # ... scale 0 reads exact torques and quantised angles
        np.testing.assert_allclose(o0[6:8] * TORQUE_SCALE, tau0, rtol=0, atol=1e-5)
        np.testing.assert_allclose(o0[0:2] * ANGLE_SCALE / Q,
                                   np.round(o0[0:2] * ANGLE_SCALE / Q), rtol=0, atol=1e-3)
    # ... while scale 1 reads offset, noisy torques
    assert not np.allclose(np.array([r[0][6:8] for r in runs[1.0]]) * TORQUE_SCALE,
                           np.array([r[2] for r in runs[1.0]]), rtol=0, atol=1e-3)
    obs0 = np.array([r[0] for r in runs[0.0]])
    obs1 = np.array([r[0] for r in runs[1.0]])
    assert not np.array_equal(obs0, obs1)
