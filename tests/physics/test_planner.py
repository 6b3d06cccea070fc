"""Tests of the quasi-static planners (softhand_env.quasistatic.planner)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softhand_env import quasistatic as qs
from softhand_env.physics.params import load_hand_params
from softhand_env.quasistatic import planner as pl

DEG = math.pi / 180


@pytest.fixture(scope="module")
def params():
    return load_hand_params("paper_ch4")


def _replay(plan, params):
    """Run approach + set-points from the open hand through the solver (independent of the
    planner's own prediction)."""
    th = np.vstack([plan.approach, plan.setpoints[1:]])
    return qs.solve_path(th, params).final


def _check_sequence(plan, step=qs.DEFAULT_STEP):
    g = plan.setpoints[0]
    assert np.allclose(plan.approach[-1], g, atol=0)
    assert np.allclose(plan.approach[0], qs.initial_state().theta)
    for seq in (plan.approach, plan.setpoints):
        assert np.all(np.isfinite(seq)) and seq.shape[1] == 2
        if len(seq) > 1:
            assert np.max(np.abs(np.diff(seq, axis=0))) <= step * (1 + 1e-9)


@pytest.mark.parametrize("target_mm", [-25.0, -12.5, -0.3, 0.0, 7.0, 26.9])
def test_plan_translation_round_trip(params, target_mm):
    plan = pl.plan_translation(target_mm * 1e-3, params)
    _check_sequence(plan)
    assert np.allclose(plan.setpoints[0], [6 * DEG, 6 * DEG])
    # rotation only: theta_1 - g = -(theta_2 - g) on every set-point
    dev = plan.setpoints - plan.setpoints[0]
    assert np.allclose(dev[:, 0], -dev[:, 1], atol=1e-15)
    fin = _replay(plan, params)
    # planner tolerance 1e-6 m; measured errors ~1e-16 m (the bracketing solve is exact)
    assert abs(fin.x - target_mm * 1e-3) <= 1e-6
    assert abs(plan.error[0]) <= 1e-6 and math.isnan(plan.error[1])
    assert np.allclose(fin.pose, plan.final.pose, atol=1e-15)


def test_plan_translation_other_grasp_and_step(params):
    plan = pl.plan_translation(-0.015, params, grasp_angle=3.6 * DEG, step=0.05 * DEG)
    _check_sequence(plan, 0.05 * DEG)
    assert abs(_replay(plan, params).x + 0.015) <= 1e-6


@pytest.mark.parametrize("target", [-0.03, 0.0275, 0.1, -1.0])
def test_plan_translation_unreachable(params, target):
    # reachable with |phi| <= 20 deg from the 6 deg grasp: |x| <= 27.02 mm
    with pytest.raises(ValueError, match="not reachable"):
        pl.plan_translation(target, params)


def test_plan_translation_larger_rotation_reaches_further(params):
    plan = pl.plan_translation(-0.03, params, max_rotation=25 * DEG)
    assert abs(_replay(plan, params).x + 0.03) <= 1e-6
    assert plan.n_base_violation > 0
    with pytest.raises(ValueError, match="beyond the fingertip base"):
        pl.plan_translation(-0.03, params, max_rotation=25 * DEG, allow_base_violation=False)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), "1", None])
def test_plan_translation_input_validation(params, bad):
    with pytest.raises(ValueError, match="target_x"):
        pl.plan_translation(bad, params)
    with pytest.raises(ValueError, match="grasp_angle"):
        pl.plan_translation(0.0, params, grasp_angle=bad)


def test_plan_translation_grasp_must_squeeze(params):
    with pytest.raises(ValueError, match="first-touch"):
        pl.plan_translation(0.0, params, grasp_angle=-1 * DEG)


@pytest.mark.parametrize("x_mm, theta_deg", [(-13.7, -9.7), (-13.7, -8.5), (10.0, 8.0),
                                             (20.0, 14.0)])
def test_plan_pose_round_trip(params, x_mm, theta_deg):
    plan = pl.plan_pose(x_mm * 1e-3, theta_deg * DEG, params)
    _check_sequence(plan)
    fin = _replay(plan, params)
    # planner tolerances 1e-6 m and 1e-5 rad; measured <= 2e-8 m and 2e-7 rad
    assert abs(fin.x - x_mm * 1e-3) <= 1e-6
    assert abs(fin.theta_obj - theta_deg * DEG) <= 1e-5
    d = plan.predicted.d
    assert d.min() >= 1e-3 and d.max() <= 0.6 * params.a


@pytest.mark.parametrize(
    "x_mm, theta_deg, match",
    [
        (0.0, 2.0, "not reachable"),  # at x = 0 theta_obj = 0 for every straight path
        (10.0, 5.0, "not reachable"),
        (-13.7, -11.0, "squeeze_limits"),
        (-40.0, -30.0, "squeeze_limits"),
        (-70.0, -45.0, "not reachable"),
    ],
)
def test_plan_pose_unreachable(params, x_mm, theta_deg, match):
    with pytest.raises(ValueError, match=match):
        pl.plan_pose(x_mm * 1e-3, theta_deg * DEG, params)


def test_plan_pose_input_validation(params):
    with pytest.raises(ValueError, match="target_theta"):
        pl.plan_pose(0.0, float("nan"), params)
    with pytest.raises(ValueError, match="squeeze_limits"):
        pl.plan_pose(0.0, 0.0, params, squeeze_limits=(0.01, 0.005))


@pytest.mark.parametrize("target_deg", [-12.0, 3.0, 15.0])
def test_plan_reorientation_round_trip(target_deg):
    from softhand_env.quasistatic.planner import plan_reorientation

    target = math.radians(target_deg)
    plan = plan_reorientation(target)
    replay = qs.solve_path(plan.setpoints, None, plan.grasp_state)
    assert abs(replay.theta_obj[-1] - target) <= 1e-7
    steps = np.abs(np.diff(plan.setpoints, axis=0)).max()
    assert steps <= math.radians(0.1) * (1 + 1e-9)


def test_plan_reorientation_rejects_unreachable_targets():
    from softhand_env.quasistatic.planner import plan_reorientation

    with pytest.raises(ValueError, match="target_theta"):
        plan_reorientation(math.radians(40.0))
