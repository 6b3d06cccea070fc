"""The set-point ramp (``setpoint_ramp_ms``): a control step's set-points move to the new
command in 10 ms stairs, which is what an agent commanding every stair at a 10 ms control
period gets."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from softhand_env.envs.signature import env_signature, signature_differences

ABSOLUTE = {"action_mode": "absolute", "normalize_action": False}
RK4 = {"hand_overrides": {"integrator": "rk4"}}
# set-points (rad) of a few control steps: opening, closing, rolling, holding
COMMANDS = np.radians([[2.0, 2.0], [9.0, 7.0], [4.0, 11.0], [4.0, 11.0], [10.0, 3.0]])


def _pose(env: gym.Env) -> np.ndarray:
    return env.unwrapped.physics.get_state().copy()


@pytest.mark.parametrize("ramp_ms, control_dt", [(40.0, 0.08), (80.0, 0.08), (30.0, 0.05)])
def test_ramp_equals_commanding_every_stair(ramp_ms, control_dt):
    """A step of ``control_dt`` with a ramp of K stairs equals K steps of 10 ms commanding
    the previous set-points plus (k + 1) / K of the change, then 10 ms steps holding the
    command: the same states bit for bit (slip windows of 20 ms in both; RK4, whose substeps
    do not depend on where a call ends, unlike the ROS2 steps after each call's start)."""
    ramped = gym.make("SoftHandPose-v1", control_dt=control_dt, setpoint_ramp_ms=ramp_ms,
                      **RK4, **ABSOLUTE)
    fine = gym.make("SoftHandPose-v1", control_dt=0.01, **RK4, **ABSOLUTE)
    ramped.reset(seed=7)
    fine.reset(seed=7)
    assert np.array_equal(_pose(ramped), _pose(fine))
    prev = fine.unwrapped.physics.step_arrays()[1][0].copy()
    stairs, per_step = round(ramp_ms / 10), round(control_dt / 0.01)
    for u in COMMANDS:
        _, _, term_r, _, info_r = ramped.step(u)
        for k in range(per_step):
            stair = prev + (u - prev) * ((k + 1) / stairs) if k + 1 < stairs else u
            _, _, term_f, _, info_f = fine.step(stair)
            if term_f:
                break
        assert term_r == term_f
        assert np.array_equal(_pose(ramped), _pose(fine))
        assert info_r["termination_reason"] == info_f["termination_reason"]
        prev = u
        if term_r:
            break


def test_ramp_changes_the_motion_and_zero_is_the_jump():
    """A ramp slows the set-point change (a different state after the step); 0 ms is the
    default, bit for bit."""
    kw = {"control_dt": 0.08, **ABSOLUTE}
    states = []
    for extra in ({}, {"setpoint_ramp_ms": 0.0}, {"setpoint_ramp_ms": 80.0}):
        env = gym.make("SoftHandPose-v1", **kw, **extra)
        env.reset(seed=3)
        env.step(COMMANDS[1])
        states.append(_pose(env))
    assert np.array_equal(states[0], states[1])
    assert not np.allclose(states[0], states[2])


def test_single_env_equals_vector_row():
    """The single env (which then steps through the batched path) and row 0 of the native
    vector env give the same episode with a ramp."""
    kw = {"control_dt": 0.16, "max_delta_deg": 8.0, "setpoint_ramp_ms": 80.0}
    env = gym.make("SoftHandPoseRandom-v1", **kw)
    vec = gym.make_vec("SoftHandPoseRandom-v1", num_envs=2,
                       vectorization_mode="vector_entry_point", **kw)
    obs, _ = env.reset(seed=11)
    vobs, _ = vec.reset(seed=[11, 12])
    assert np.array_equal(obs, vobs[0])
    rng = np.random.default_rng(0)
    for _ in range(6):
        a = rng.uniform(-1, 1, 2).astype(np.float32)
        obs, r, term, _, _ = env.step(a)
        vobs, vr, vterm, _, _ = vec.step(np.stack([a, a]))
        assert np.array_equal(obs, vobs[0]) and r == vr[0] and term == vterm[0]
        if term:
            break


@pytest.mark.parametrize("kw, message", [
    ({"setpoint_ramp_ms": 25.0}, "multiple of 10 ms"),
    ({"setpoint_ramp_ms": 30.0, "control_dt": 0.02}, "at most control_dt"),
    ({"setpoint_ramp_ms": -10.0}, r"setpoint_ramp_ms must be a number in \[0"),
    ({"setpoint_ramp_ms": float("nan")}, "setpoint_ramp_ms"),
])
def test_bad_ramps_are_refused(kw, message):
    with pytest.raises(ValueError, match=message):
        gym.make("SoftHandPose-v1", **kw)


def test_ramp_needs_slip_windows():
    with pytest.raises(ValueError, match="set slip_window_ms"):
        gym.make("SoftHandPose-v0", control_dt=0.08, setpoint_ramp_ms=40.0)


def test_signature_tells_a_ramped_model_from_a_jumping_one():
    ramped = gym.make("SoftHandPose-v1", control_dt=0.08, setpoint_ramp_ms=40.0)
    plain = gym.make("SoftHandPose-v1", control_dt=0.08)
    sig = env_signature(ramped)
    assert sig["setpoint_ramp_ms"] == pytest.approx(40.0)
    assert list(signature_differences(sig, plain)) == ["setpoint_ramp_ms"]
    # a signature saved before the field existed reads 0 ms: it fits the plain env only
    legacy = {k: v for k, v in env_signature(plain).items() if k != "setpoint_ramp_ms"}
    assert not signature_differences(legacy, plain)
    assert list(signature_differences(legacy, ramped)) == ["setpoint_ramp_ms"]
