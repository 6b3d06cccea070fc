"""Rendering: headless rgb_array frames show the scene; human mode opens a (dummy) window."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from softhand_env.envs.rendering import FINGERTIP, GOAL, OBJECT


def _count(frame, color):
    return int(np.all(frame == np.array(color, dtype=np.uint8), axis=-1).sum())


def test_rgb_array_frame_shows_hand_object_and_goal():
    env = gym.make("SoftHandPose-v0", render_mode="rgb_array", render_width=320,
                   render_height=240)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert _count(frame, OBJECT) > 500 and _count(frame, FINGERTIP) > 200
    assert _count(frame, GOAL) > 50
    assert env.metadata["render_fps"] == pytest.approx(50.0)
    # frames follow the state and are copies
    for _ in range(10):
        env.step(np.array([1.0, -1.0], dtype=np.float32))
    frame2 = env.render()
    assert not np.array_equal(frame, frame2)
    frame2[:] = 0
    assert env.render().any()


def test_fingertips_flatten_with_deformation():
    # more squeeze -> larger d_n -> fewer fingertip pixels (flattened against the object)
    areas = []
    for grasp in (3.0, 7.0):
        env = gym.make("SoftHand-v0", render_mode="rgb_array", grasp_setpoint_deg=(grasp, grasp))
        _, info = env.reset(seed=0)
        areas.append((info["deformation"][0], _count(env.render(), FINGERTIP)))
    (dn_small, area_small), (dn_large, area_large) = areas
    assert dn_large > dn_small and area_large < area_small


def test_no_task_has_no_goal_and_no_render_mode_warns():
    env = gym.make("SoftHand-v0", render_mode="rgb_array")
    env.reset(seed=0)
    assert _count(env.render(), GOAL) == 0
    plain = gym.make("SoftHand-v0").unwrapped
    plain.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert plain.render() is None


def test_human_mode_opens_a_window(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    pytest.importorskip("pygame")
    env = gym.make("SoftHandReorient-v0", render_mode="human", render_width=64, render_height=64)
    env.reset(seed=0)  # renders
    _, _, _, _, _ = env.step(np.zeros(2, dtype=np.float32))
    assert env.render() is None
    assert env.unwrapped._viewer is not None
    env.close()
    assert env.unwrapped._viewer is None


@pytest.mark.parametrize("mode", [1, "rgb_array_list", "video"])
def test_gym_make_refuses_a_bad_render_mode_with_a_clear_error(mode):
    # gym.make itself must not choke on a non-string mode: the env's own check names the field
    with pytest.raises(ValueError, match="render_mode must be None or one of"):
        gym.make("SoftHandReorient-v0", render_mode=mode)
