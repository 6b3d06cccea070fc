"""Slip-window analysis: fine replays reproduce the play; windows sum the fine impulses."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from softhand_env.physics.friction import friction_ratio
from softhand_env.tools import slip_windows as sw


def test_window_impulses_tiled_and_sliding():
    imp = np.arange(28.0).reshape(7, 4)
    sums, ends = sw.window_impulses(imp, 3)
    np.testing.assert_array_equal(ends, [3, 6, 7])  # the last window is the rest
    np.testing.assert_array_equal(sums[0], imp[:3].sum(0))
    np.testing.assert_array_equal(sums[2], imp[6])
    sl, ends_s = sw.window_impulses(imp, 3, sliding=True)
    np.testing.assert_array_equal(ends_s, [3, 4, 5, 6, 7])
    np.testing.assert_array_equal(sl[1], imp[1:4].sum(0))
    with pytest.raises(ValueError, match=">= 1"):
        sw.window_impulses(imp, 0)


def test_ratio_counts_tension_as_inf():
    imp = np.array([[1.0, 2.0, 0.5, -1.0], [-1e-6, 1.0, 0.0, 0.1]])
    np.testing.assert_array_equal(sw.ratio_of(imp), [0.5, math.inf])
    np.testing.assert_array_equal(sw.ratio_of(imp), friction_ratio(imp).max(axis=1))


@pytest.fixture(scope="module")
def paper_short():
    # motions 1-3 of the paper, 0.2 s each, 20 ms steps
    policy = sw.HeldSetpoints(np.radians([(6, 6), (20, -10), (-2, 13)]), 10)

    def make():
        return gym.make("SoftHand-v0", action_mode="absolute", normalize_action=False,
                        grasp_duration=0.0, max_episode_steps=policy.episode_steps)

    return sw.run_source(make, policy, [0])


def test_replay_reproduces_the_play_and_its_step_ratios(paper_short):
    (rec,), (rp,) = paper_short
    assert rec.setpoints.shape == (30, 2) and rec.control_dt == pytest.approx(0.02)
    # the same RK4 substeps under the same set-points: the same trajectory, to the bit
    assert rp.pose_error == 0.0
    assert rp.impulse.shape == (600, 4)
    np.testing.assert_array_equal(rp.jumps, [200, 400])  # motion 1 = the grasp set-points
    # 20 ms windows tiled from the start are the play's own control steps
    r20 = sw.ratio_of(sw.window_impulses(rp.impulse, 20)[0])
    assert r20.max() == pytest.approx(rec.step_ratio, rel=1e-9)


def test_analyse_short_windows_see_the_jump_transient(paper_short):
    _, reps = paper_short
    stats = {s.window_ms: s for s in sw.analyse(reps, (1, 20))}
    # right after the 16 deg jump of motion 2 the 1 ms window pulls (J_n < 0)
    assert stats[1].n_tension == 1 and stats[1].peak == math.inf
    assert stats[1].lag_ms == pytest.approx(1.0)
    assert stats[20].n_exceed == 0 and stats[20].peak < 1.0
    assert "| 20 |" in sw.format_stats("t", list(stats.values()))


def test_replay_keywords_and_bad_periods(paper_short):
    (rec,), _ = paper_short
    kw = sw.replay_kwargs(rec)
    assert kw["control_dt"] == sw.FINE_DT and kw["terminate_on_slip"] is False
    assert kw["action_mode"] == "absolute" and kw["normalize_action"] is False
    assert "terminate_on_success" not in kw or kw["terminate_on_success"] is None
    gym.make(rec.env_id, **kw).close()  # valid keywords for the task-free id
    with pytest.raises(ValueError, match="whole multiple"):
        sw.replay_fine(rec, fine_dt=0.003)


def test_time_constants_follow_table_5_1():
    tc = sw.time_constants(d_n=0.007)
    assert tc["k_t"] == pytest.approx(2 * math.pi * 0.232e6 * 0.007)
    assert tc["tau_t"] == pytest.approx(300.0 / tc["k_t"])
    assert 0.025 < tc["tau_t"] < 0.035 and tc["tau_pid"] == pytest.approx(14.0 / 300.0)
