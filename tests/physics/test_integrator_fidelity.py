"""ROS2 at its default step against RK4 at 0.1 ms: the fidelity gates of the fast integrator.

Both integrators play the paper's motions 1-8 (1 s each, from the parallel point-contact
state) in control periods of 20 ms, the environments' period, and are compared at the end of
every period: object position (x, y) in mm, angles (theta_obj, theta_1, theta_2) in deg,
constraint residuals, and the friction ratios of every period. The gates are fixed bounds
(end poses within 0.05 mm / 0.05 deg, the whole run within 0.1 mm / 0.1 deg, friction ratios
within 0.02, |C^H| <= 1e-8 m, |C^N| <= 1e-6 m/s); the measured values are in the comments.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from softhand_env.physics import HandPhysics, rosenbrock
from softhand_env.physics.motions import PAPER_MOTIONS_DEG
from softhand_env.physics.params import HandParams

RK4 = HandParams()
ROS2 = HandParams(integrator="ros2")
PERIOD = 200  # substeps of 0.1 ms: 20 ms
PER_MOTION = 50  # 1 s


def play(params: HandParams) -> dict[str, np.ndarray]:
    """Motions 1-8 in 20 ms periods: states (K, 20) at the end of each period, its friction
    ratios (K, 2), max |C^H| and |C^N| (K,)."""
    physics = HandPhysics(params)
    ys, ratios, ch, cn = [], [], [], []
    for u in np.radians(PAPER_MOTIONS_DEG):
        for _ in range(PER_MOTION):
            status = physics.step(u, PERIOD)
            assert status.flags == 0
            ys.append(physics.get_state())
            ratios.append(status.friction_ratio)
            ch.append(status.max_ch)
            cn.append(status.max_cn)
    return {"y": np.array(ys), "ratio": np.array(ratios), "ch": np.array(ch),
            "cn": np.array(cn)}


@pytest.fixture(scope="module")
def runs() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    return play(RK4), play(ROS2)


def _errors(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Largest position (mm) and angle (deg) difference between state arrays (K, 20)."""
    pos = 1e3 * np.abs(a[:, 0:2] - b[:, 0:2]).max()
    ang = math.degrees(np.abs(a[:, 2:5] - b[:, 2:5]).max())
    return float(pos), float(ang)


def test_default_step_is_one_millisecond():
    assert ROS2.ros2_dt == 1e-3 and ROS2.dt == RK4.dt == 1e-4


def test_paper_motions_end_poses_match_rk4(runs):
    rk4, ros2 = runs
    ends = np.arange(1, len(PAPER_MOTIONS_DEG) + 1) * PER_MOTION - 1
    pos, ang = _errors(rk4["y"][ends], ros2["y"][ends])
    # measured 0.035 mm, 0.026 deg
    assert pos <= 0.05 and ang <= 0.05, (pos, ang)


def test_paper_motions_whole_trajectory_matches_rk4(runs):
    rk4, ros2 = runs
    pos, ang = _errors(rk4["y"], ros2["y"])
    # measured 0.040 mm, 0.081 deg
    assert pos <= 0.1 and ang <= 0.1, (pos, ang)
    # the deformations too (measured 0.011 mm)
    assert 1e3 * np.abs(rk4["y"][:, 5:9] - ros2["y"][:, 5:9]).max() <= 0.05


def test_constraint_errors_are_round_off_with_projection(runs):
    _, ros2 = runs
    # the gates (|C^H| <= 1e-8 m, |C^N| <= 1e-6 m/s) hold over the whole run, switching
    # instants included; measured 2.7e-11 m (the first stage after a jump) and 1.1e-16 m/s
    assert ros2["ch"].max() <= 1e-8 and ros2["cn"].max() <= 1e-6
    assert ros2["ch"].max() <= 1e-10 and ros2["cn"].max() <= 1e-14


def test_friction_ratios_match_rk4(runs):
    rk4, ros2 = runs
    diff = np.abs(rk4["ratio"] - ros2["ratio"]).max()
    # measured 0.0060 (largest in the periods with a set-point jump); max ratio 0.541
    assert diff <= 0.02, diff
    assert 0.5 < ros2["ratio"].max() < 0.6


def test_ros2_converges_at_second_order_down_to_its_default_step():
    """Whole run (every 20 ms period) against RK4 at 0.05 ms, as the convergence figure of
    docs/integrator.md. Measured: position 0.389, 0.239, 0.040 mm and angles 0.463, 0.352,
    0.081 deg at ros2_dt = 4, 2, 1 ms (orders 0.7, 2.6 and 0.4, 2.1). Every step of a call
    scales with ros2_dt except where the call is too short for the schedule: at 4 ms a 20 ms
    call is the ramp and four steps of 4 ms, at 2 ms its tail steps are 4 ms too, so only
    the 2 -> 1 ms refinement halves every step and shows the method's order."""
    from softhand_env.tools.integrator_convergence import errors, orders
    from softhand_env.tools.integrator_convergence import play as play20

    ref = play20(RK4.replace(dt=5e-5))
    steps = (4e-3, 2e-3, 1e-3)
    errs = [errors(play20(ROS2.replace(ros2_dt=h)), ref) for h in steps]
    pos = orders(steps, [e[0] for e in errs])
    ang = orders(steps, [e[1] for e in errs])
    assert pos[1] >= 1.8 and ang[1] >= 1.8, (errs, pos, ang)
    # at the default step, the whole-trajectory gate (0.1 mm / 0.1 deg) against this finer
    # reference too
    assert errs[-1][0] <= 0.1 and errs[-1][1] <= 0.1


def test_step_schedule_covers_the_call_and_starts_with_the_ramp():
    sched = rosenbrock.step_schedule(0.02, 1e-3)
    assert sched.sum() == pytest.approx(0.02, rel=1e-12)
    np.testing.assert_allclose(sched[:4], [1.25e-4, 1.25e-4, 2.5e-4, 5e-4])
    # then FINE_STEPS steps of H, then the rest (16 ms) in steps of at most 2 H
    np.testing.assert_allclose(sched[4:7], [1e-3] * 3)
    np.testing.assert_allclose(sched[7:], [2e-3] * 8)
    assert len(sched) == 4 + 3 + 8
    assert sched.max() <= rosenbrock.largest_step(1e-3) * (1 + 1e-12)
    # a tail that is no multiple of 2 H: equal steps below 2 H
    odd = rosenbrock.step_schedule(0.0095, 1e-3)
    assert odd.sum() == pytest.approx(0.0095, rel=1e-12) and len(odd) == 4 + 3 + 3
    np.testing.assert_allclose(odd[7:], [5.5e-3 / 3] * 3)
    # a call of at most (1 + FINE_STEPS) H: the rest after the ramp in equal steps <= H
    mid = rosenbrock.step_schedule(0.0035, 1e-3)
    np.testing.assert_allclose(mid[4:], [2.5e-3 / 3] * 3)
    short = rosenbrock.step_schedule(5e-4, 1e-3)
    assert short.sum() == pytest.approx(5e-4) and len(short) == 4
    # RHS evaluations: 2 per step, 1 at the end (RK4 at 0.1 ms: 4 per substep + 1)
    assert rosenbrock.rhs_evaluations(0.02, 1e-3) == 2 * 15 + 1
    assert len(rosenbrock.step_schedule(0.2, 1e-3)) == 4 + 3 + 98
