"""Text overlays on rendered frames (evaluation GIFs, the teleoperation window)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softhand_env.figures.overlay import annotate_episode, episode_caption, overlay_text


def test_caption_names_time_goal_and_pose_in_display_units():
    lines = episode_caption(1.234, ("x", "theta"), (0.0032, math.radians(-5.1)),
                            (0.001, 0.07, math.radians(2.0)))
    assert lines == ["t = 1.23 s", "goal  x* = +3.2 mm   θ* = -5.1°",
                     "now   x = +1.0 mm   θ = +2.0°"]
    assert episode_caption(0.5) == ["t = 0.50 s", "no goal (replay)"]
    with pytest.raises(ValueError, match="goal has 1 entries"):
        episode_caption(0.0, ("x", "theta"), (0.0,))


def test_overlay_draws_a_box_in_the_chosen_corner_only():
    frame = np.full((120, 160, 3), 240, dtype=np.uint8)
    top = overlay_text(frame, ["t = 0.00 s"])
    bottom = overlay_text(frame, ["t = 0.00 s"], corner="bottom")
    assert top.shape == frame.shape and top.dtype == np.uint8
    assert np.array_equal(frame, np.full((120, 160, 3), 240))  # input untouched
    changed_top = np.argwhere((top != frame).any(axis=2))
    changed_bottom = np.argwhere((bottom != frame).any(axis=2))
    assert changed_top[:, 0].max() < 30 and changed_bottom[:, 0].min() > 90
    assert (top[:30] < 100).all(axis=2).sum() > 20  # dark text pixels
    with pytest.raises(ValueError, match="uint8"):
        overlay_text(frame.astype(float), ["x"])


def test_annotate_episode_stamps_each_frame_with_its_time():
    frames = [np.full((96, 96, 3), 200, dtype=np.uint8) for _ in range(3)]
    poses = np.zeros((3, 3))
    out = annotate_episode(frames, 0.02, ("x",), (0.001,), poses)
    assert len(out) == 3 and not np.array_equal(out[0], out[2])  # "t = 0.00 s" vs "0.04 s"
    assert not np.array_equal(out[0], frames[0])
    with pytest.raises(ValueError, match="2 poses for 3 frames"):
        annotate_episode(frames, 0.02, ("x",), (0.001,), poses[:2])
