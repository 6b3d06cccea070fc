"""Evaluation figures: honest titles, mathtext legends, the animated episode and its overlay."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.plots.episodes import (
    choose_episode,
    evaluation_title,
    gif_frames,
    object_motion,
    plot_episodes,
)


def episode(dx_mm: float, dth_deg: float, success: bool, goal=(0.001,), k: int = 30):
    s = np.linspace(0.0, 1.0, k + 1)
    pose = np.stack([dx_mm * 1e-3 * s, 0.07 + 0 * s, math.radians(dth_deg) * s], axis=1)
    setpoint = np.radians(6.0 + np.stack([s, -s], axis=1))
    return {"pose": pose, "setpoint": setpoint, "goal": list(goal), "success": success}


def test_titles_say_what_was_played():
    assert evaluation_title("SoftHand-v0", "paper", 1, 10000, ()) == (
        "SoftHand-v0, paper policy, 1 episode without a goal (seed 10000)")
    assert evaluation_title("SoftHandPose-v0", "ppo", 20, 10000, ("x", "theta")) == (
        "SoftHandPose-v0, ppo policy, 20 test goals (seeds 10000..10019)")
    # the goal family is named from the seeds: test, validation, or neither
    assert "1 goal (seed 5)" in evaluation_title("SoftHandTranslate-v0", "ppo", 1, 5, ("x",))
    assert "5 validation goals (seeds 5000..5004)" in evaluation_title(
        "SoftHandTranslate-v0", "ppo", 5, 5000, ("x",))
    assert "2 test goals (seeds 9999..10000)" in evaluation_title(
        "SoftHandTranslate-v0", "ppo", 2, 9999, ("x",))
    assert "1 validation goal (seed 9999)" in evaluation_title(
        "SoftHandTranslate-v0", "ppo", 1, 9999, ("x",))


def test_the_animated_episode_is_the_successful_one_that_moves_most():
    eps = [episode(0.1, 0.0, True), episode(9.0, 0.0, False), episode(0.0, 3.0, True),
           episode(2.0, 0.5, True)]
    assert object_motion(eps[2]) == pytest.approx(3.0)
    assert choose_episode(eps) == 2  # 3 deg beats 2 mm; the failure (9 mm) is not shown
    assert choose_episode([episode(0.1, 0, False), episode(4.0, 0, False)]) == 1
    with pytest.raises(ValueError, match="no episodes"):
        choose_episode([])


def test_trajectory_plot_uses_mathtext_and_an_honest_title(tmp_path):
    eps = [episode(float(k), 0.0, True) for k in range(12)]
    fig = plot_episodes(tmp_path / "t.png", eps, ("x",), 0.02, "T", highlight=11)
    assert (tmp_path / "t.png").stat().st_size > 10_000
    texts = [t.get_text() for ax in fig.axes if ax.get_legend()
             for t in ax.get_legend().get_texts()]
    assert r"$\theta_1^d$ (right)" in texts and r"$\theta_2^d$ (left)" in texts
    assert not any("theta_1^d" in t and not t.startswith("$") for t in texts)
    assert fig.axes[3].get_xlabel() == r"$\theta_1^d$ (deg)"
    title = fig._suptitle.get_text()
    assert title == "T\nobject pose of episodes 0-8 and 11 of 12, episode 11 bold, goals dashed"
    bold = [ln for ln in fig.axes[0].get_lines() if ln.get_linewidth() == 2.0]
    assert len(bold) == 1 and bold[0].get_ydata()[-1] == pytest.approx(11.0)
    fig = plot_episodes(tmp_path / "u.png", [episode(1.0, 1.0, False, goal=())], (), 0.02, "U")
    assert fig._suptitle.get_text() == "U\nobject pose of the episode"


def test_gif_frames_carry_time_and_goal_at_real_time_speed():
    frames = [np.full((120, 120, 3), 230, dtype=np.uint8) for _ in range(11)]
    poses = np.zeros((11, 3))
    shown, duration_ms = gif_frames(frames, 0.02, ("x",), (0.002,), poses, fps=25)
    assert len(shown) == 6 and duration_ms == pytest.approx(40.0)  # every 2nd 20-ms frame
    for frame in shown:
        assert frame.shape == (120, 120, 3)
        assert (frame[:30] < 100).all(axis=2).sum() > 30  # dark text on the light box
        assert np.array_equal(frame[60:], frames[0][60:])  # the scene below is untouched
    assert not np.array_equal(shown[0][:12], shown[1][:12])  # t = 0.00 s vs t = 0.04 s
