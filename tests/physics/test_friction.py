"""Contact impulses of a control step, the friction ratio, tension, and the friction coefficient.

The kernel integrates the constraint forces lambda_H (normal) and lambda_N (tangential) with
the RK4 weights of each substep (kernel.N_STEP_DIAG diag); physics.friction judges a
control step by |J_t| / J_n. Measured values quoted below are from Table 5.1 at dt = 0.1 ms
with 20 ms control steps (200 substeps), the environments' control period.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from softhand_env.physics import HandPhysics, friction, kernel
from softhand_env.physics.model import pack_params
from softhand_env.physics.motions import PAPER_MOTIONS_DEG
from softhand_env.physics.params import HandParams, hand_params_from_dict, load_hand_params
from softhand_env.quasistatic import handling_path

PARAMS = HandParams()
STEP = 200  # substeps per 20 ms control step
MOTIONS = np.radians(PAPER_MOTIONS_DEG)


def replay(physics: HandPhysics, motions, steps_per_motion: int = 50):
    """Control-step impulses (K, 4) of ``motions`` held ``steps_per_motion`` steps each."""
    out = []
    for u in motions:
        for _ in range(steps_per_motion):
            status = physics.step(u, STEP)
            assert not status.fatal, status.reasons
            out.append(status.impulse)
    return np.array(out)


@pytest.fixture(scope="module")
def paper_impulses():
    physics = HandPhysics(PARAMS)
    physics.reset()
    return replay(physics, MOTIONS)


# ------------------------------------------------------------------------ ratio functions
def test_ratio_tension_and_slip_functions():
    imp = np.array([[2.0, 1.0, -0.5, 0.25], [0.0, -1.0, 0.1, 0.0]])
    np.testing.assert_array_equal(friction.friction_ratio(imp), [[0.25, 0.25], [np.inf, np.inf]])
    np.testing.assert_array_equal(friction.tension(imp), [[False, False], [False, True]])
    np.testing.assert_array_equal(friction.slipping(imp, 0.2), [[True, True], [True, True]])
    np.testing.assert_array_equal(friction.slipping(imp, [[0.3], [0.3]])[0], [False, False])
    with pytest.raises(ValueError, match="shape"):
        friction.friction_ratio(np.zeros(3))


# ------------------------------------------------------------------------ kernel impulses
def test_impulse_is_the_integral_of_the_constraint_forces():
    """Against an independent quadrature: the trapezoid rule over the stage-1 multipliers
    sampled every substep (HandPhysics.diagnostics), in a settled grasp (smooth forces).
    Measured relative difference <= 8.5e-12; bar 1e-10."""
    physics = HandPhysics(PARAMS)
    assert not physics.step(MOTIONS[0], 5000).fatal
    assert not physics.step(MOTIONS[1], 5000).fatal
    lam = [physics.diagnostics()["lambda"]]
    J = np.zeros(4)
    for _ in range(STEP):
        J += physics.step(MOTIONS[1], 1).impulse
        lam.append(physics.diagnostics()["lambda"])
    lam = np.array(lam)
    trapezoid = PARAMS.dt * (lam[1:-1].sum(0) + 0.5 * (lam[0] + lam[-1]))
    np.testing.assert_allclose(J, trapezoid, rtol=1e-10)
    # normal forces push; the tangential ones are not small (theta_p ~ 30 deg)
    assert np.all(J[:2] > 0) and np.all(np.abs(J[2:]) > 0.1 * J[:2])


def test_impulse_of_a_call_is_the_sum_of_its_substeps():
    """The accumulation runs substep after substep: a 200-substep call and 200 calls of one
    substep give the same state and the same impulse, bit for bit."""
    a, b = HandPhysics(PARAMS), HandPhysics(PARAMS)
    a.step(MOTIONS[0], 3000)
    b.set_state(a.get_state())
    whole = a.step(MOTIONS[1], STEP).impulse
    parts = np.zeros(4)
    for _ in range(STEP):
        parts = parts + b.step(MOTIONS[1], 1).impulse
    np.testing.assert_array_equal(a.get_state(), b.get_state())
    np.testing.assert_array_equal(whole, parts)


def test_short_diag_rows_receive_what_they_have_room_for():
    """Callers that allocate the residual-only diag (2,) or residuals and substeps (3,) keep
    working (impulses not written); the full row (N_STEP_DIAG = 7) is [max|C^H|, max|C^N|,
    substeps taken, J_n1, J_n2, J_t1, J_t2]."""
    y = HandPhysics(PARAMS).get_state()
    prm = pack_params(PARAMS)
    d2, d3, d7 = np.zeros(2), np.zeros(3), np.zeros(kernel.N_STEP_DIAG)
    for d in (d2, d3, d7):
        kernel.advance(y.copy(), MOTIONS[0], prm, 100, kernel.CH_LIMIT, d)
    assert kernel.N_STEP_DIAG == 7 and kernel.IMPULSE_OFFSET == 3
    np.testing.assert_array_equal(d2, d7[:2])
    np.testing.assert_array_equal(d3, d7[:3])
    assert d7[2] == 100
    assert np.all(d7[3:5] > 0)


def test_impulse_counts_the_substeps_up_to_a_fatal_stop():
    """Opening the hand loses the grasp mid-call: the impulse covers the substeps taken."""
    a, b = HandPhysics(PARAMS), HandPhysics(PARAMS)
    a.step(MOTIONS[0], 3000)
    b.set_state(a.get_state())
    status = a.step(np.radians([-20.0, -20.0]), 5000, strict=False)
    assert status.fatal and status.substeps < 5000
    again = b.step(np.radians([-20.0, -20.0]), status.substeps, strict=False)
    np.testing.assert_array_equal(status.impulse, again.impulse)


# ------------------------------------------------------------------------ the transient case
def test_set_point_jump_transient_does_not_decide_the_step_ratio():
    """Motion 7 (-15, 25 deg) after motions 1-6: in the first substeps after the jump the
    instantaneous multipliers pull (lambda_H < 0 in 4 substeps, down to -512 N as the
    RK4-weighted substep mean) and the instantaneous ratio |lambda_N| / lambda_H peaks at 76,
    while over the 20 ms control step the normal impulse is positive and the ratio is 0.44
    (the settled value of motion 7 is 0.54)."""
    physics = HandPhysics(PARAMS)
    replay(physics, MOTIONS[:6])
    sub = np.array([physics.step(MOTIONS[6], 1).impulse for _ in range(STEP)])
    mean_force = sub / PARAMS.dt
    inst = friction.friction_ratio(mean_force)
    assert np.any(friction.tension(mean_force))  # pulls at substep level
    assert mean_force[:, :2].min() < -100.0  # measured -512 N
    assert np.nanmax(np.where(np.isfinite(inst), inst, np.nan)) > 10.0  # measured 76
    step = np.zeros(4)
    for s in sub:
        step = step + s
    assert not np.any(friction.tension(step))
    assert friction.friction_ratio(step).max() < 0.6  # measured 0.445


# ------------------------------------------------------------------------ paper motions
def test_paper_motions_stay_within_the_default_friction(paper_impulses):
    """Motions 1-8 need at most 0.542 (motion 7, theta_p = 42 deg, settled); no control step
    pulls (smallest normal impulse 0.44 N s); mu = 0.2 would slip, first in motion 2."""
    ratio = friction.friction_ratio(paper_impulses)
    assert 0.5 < ratio.max() < 0.55
    assert not np.any(friction.slipping(paper_impulses, PARAMS.mu))
    assert paper_impulses[:, :2].min() > 0.4
    slip = np.flatnonzero(friction.slipping(paper_impulses, 0.2).any(axis=1))
    assert slip.size and slip[0] // 50 == 1  # first slip in motion 2


def test_step_status_exposes_ratio_and_tension():
    physics = HandPhysics(PARAMS)
    status = physics.step(MOTIONS[0], STEP)
    np.testing.assert_array_equal(status.friction_ratio, friction.friction_ratio(status.impulse))
    assert status.impulse.shape == (4,) and not status.tension.any()


# ------------------------------------------------------------------------ the coefficient
def test_mu_is_a_hand_parameter_in_both_configs():
    for name in ("paper_ch5", "paper_ch4"):
        assert load_hand_params(name).mu == 1.0
    assert HandParams().mu == 1.0
    assert hand_params_from_dict({"mu": 0.2}).mu == 0.2
    assert load_hand_params("paper_ch5", mu=0.5).mu == 0.5
    assert HandParams().to_yaml_dict()["mu"] == 1.0
    for bad in (0.0, -1.0, 11.0, float("nan"), "0.5", True):
        with pytest.raises(ValueError, match="mu"):
            hand_params_from_dict({"mu": bad})
    with pytest.raises(ValueError, match="mu"):
        PARAMS.replace(mu=0.0)


def test_mu_does_not_change_the_dynamics():
    np.testing.assert_array_equal(pack_params(PARAMS), pack_params(PARAMS.replace(mu=0.2)))


# ------------------------------------------------------------------------ handling process
def handling_steps(params: HandParams, grasp_deg: float = 6.0):
    """Impulses (K, 4) and operation numbers (K,) of the §4.3 handling process at 20 ms per
    0.2 deg set-point increment, from the parallel point contact, until the grasp is lost."""
    setpoints, op = handling_path(math.radians(grasp_deg), math.radians(0.2),
                                  math.radians(20.0), 3)
    physics = HandPhysics(params)
    out, ops = [], []
    for k in range(1, len(setpoints)):
        status = physics.step(setpoints[k], STEP, strict=False)
        if status.fatal:
            break
        out.append(status.impulse)
        ops.append(op[k])
    return np.array(out), np.array(ops)


def test_handling_process_friction_and_release_tension():
    """Without gravity (chapter 4's assumption) operations 1-6 need at most 0.489 at the 6 deg
    grasp. With gravity the object hangs on friction while the squeeze builds (step 1 needs
    1.049 > mu), and opening the hand (operation 7) first slips (ratio 2.0) and then pulls:
    negative normal impulses for several control steps while d_n is still positive."""
    imp, op = handling_steps(PARAMS.replace(g=0.0))
    ratio = friction.friction_ratio(imp[op <= 6]).max()
    assert 0.48 < ratio < 0.50
    imp, op = handling_steps(PARAMS)
    first = friction.friction_ratio(imp[0]).max()
    assert 1.04 < first < 1.06 and friction.slipping(imp[0], PARAMS.mu).any()
    assert friction.friction_ratio(imp[2:][op[2:] <= 6]).max() < 0.53
    release = imp[op == 7]
    assert friction.tension(release).any(axis=1).sum() >= 5
    assert not friction.tension(imp[op <= 6]).any()


def test_compiled_contact_check_equals_the_array_functions():
    """friction.check_contact (the env's per-step check) gives exactly friction_ratio, tension
    and the slip rule of the array functions, non-finite impulses read as 0."""
    rng = np.random.default_rng(3)
    imp = rng.normal(size=(64, 4))
    imp[::7, 0] = 0.0
    imp[3, 2] = np.nan
    mu = rng.uniform(0.2, 2.0, size=64)
    failed = rng.random(64) < 0.2
    skip = rng.random(64) < 0.1
    out_imp, ratio = np.empty((64, 4)), np.empty((64, 2))
    tens, bad = np.empty((64, 2), dtype=bool), np.empty(64, dtype=bool)
    friction.check_contact(imp, mu, failed, skip, out_imp, ratio, tens, bad)
    clean = np.where(np.isfinite(imp), imp, 0.0)
    np.testing.assert_array_equal(out_imp, clean)
    np.testing.assert_array_equal(ratio, friction.friction_ratio(clean))
    np.testing.assert_array_equal(tens, friction.tension(clean))
    expect = friction.slipping(clean, mu[:, None]).any(axis=1) & ~failed & ~skip
    np.testing.assert_array_equal(bad, expect)
    assert bad.any() and not bad.all()
