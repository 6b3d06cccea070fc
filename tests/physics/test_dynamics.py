"""Integration-level acceptance of the chapter-5 model: the paper's run, symmetry, energy,
convergence order, kernel-vs-reference agreement and divergence handling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softhand_env.physics import HandPhysics, PhysicsError, kernel, model
from softhand_env.physics.integrate import RK4_A, RK4_B, RK4_C, integrate_fixed, rk_step
from softhand_env.physics.model import NQ, NY, pack_params, potential_energy
from softhand_env.physics.motions import PAPER_MOTIONS_DEG, run_paper_motions, run_setpoint_sequence
from softhand_env.physics.params import HandParams
from softhand_env.physics.reference import advance_reference, mass_matrix

PARAMS = HandParams()


@pytest.fixture(scope="module")
def paper_run():
    return run_paper_motions(PARAMS, duration=1.0)


def advance(y, u_rad, prm, n):
    diag = np.zeros(kernel.N_STEP_DIAG)
    flags, done = kernel.advance(y, np.asarray(u_rad, float), prm, n, kernel.CH_LIMIT, diag)
    assert flags == 0 and done == n, kernel_flags_message(flags)
    return diag


def kernel_flags_message(flags):
    from softhand_env.physics import describe_flags

    return f"flags {describe_flags(flags)}"


# ------------------------------------------------------------------ generic RK4 (scipy style)
def test_rk4_tableau_identities():
    assert RK4_B.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(RK4_A.sum(axis=1), RK4_C)  # row-sum condition
    # order conditions up to 4 for the quadrature part
    for k in range(1, 5):
        assert RK4_B @ RK4_C ** (k - 1) == pytest.approx(1.0 / k)


def test_generic_rk4_is_fourth_order_on_a_closed_form():
    """y' = -y + sin(t): error ratio ~16 when h halves (closed-form solution)."""

    def fun(t, y):
        return -y + np.sin(t)

    def exact(t):
        return 0.5 * (np.sin(t) - np.cos(t)) + 1.5 * np.exp(-t)

    errors = []
    # n >= 80: at n = 10-40 the error is pre-asymptotic here (it changes sign at n ~ 15)
    for n in (80, 160, 320):
        y = integrate_fixed(fun, 0.0, np.array([1.0]), 2.0 / n, n)
        errors.append(abs(y[0] - exact(2.0)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 14) & (ratios < 18)), ratios
    assert rk_step(fun, 0.0, np.array([1.0]), 0.0)[0] == 1.0


def grasp_state(duration=0.02, setpoint_deg=(6.0, 6.0), params=PARAMS):
    y = model.initial_state(params)
    advance(y, np.radians(setpoint_deg), pack_params(params), round(duration / params.dt))
    return y


def test_kernel_rk4_converges_at_fourth_order_on_the_unforced_system():
    """PID off (no input), gravity on, from a moving grasp state; reference h/32.

    Step sizes are below the Baumgarte time scale 1/alpha = 50 us so that the error is in the
    asymptotic regime; the observed order is ~4 (ratio ~16 per halving).
    """
    unforced = PARAMS.replace(Kp=0.0, Kd=0.0, Ki=0.0)
    y0 = grasp_state()
    T = 0.004

    def final(h):
        prm = pack_params(unforced.replace(dt=h))
        y = y0.copy()
        advance(y, [0.0, 0.0], prm, round(T / h))
        return y

    ref = final(1e-5 / 32)
    errors = [np.abs(final(h)[:NQ] - ref[:NQ]).max() for h in (2e-5, 1e-5, 5e-6)]
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    orders = np.log2(ratios)
    assert np.all((orders > 3.6) & (orders < 4.6)), (errors, orders)


# -------------------------------------------------------------------- paper run (§5.5.1)
def away_from_switches(run, window=0.05):
    mask = np.ones(len(run.t), bool)
    for s in run.switch_times:
        mask &= ~((run.t > s) & (run.t <= s + window + 1e-12))
    return mask


def test_paper_motions_keep_the_grasp(paper_run):
    assert len(paper_run.t) == 1 + 8 * 1000 and np.all(paper_run.flags == 0)
    dn = paper_run.y[1:, model.DN_1 : model.DN_1 + 2]
    assert dn.min() > 0.0


def test_paper_motions_constraint_errors_match_fig_5_6(paper_run):
    mask = away_from_switches(paper_run)
    assert paper_run.max_ch[mask].max() <= 1e-8
    assert paper_run.max_cn[mask].max() <= 1e-6


def test_every_paper_motion_settles(paper_run):
    for m in range(len(PAPER_MOTIONS_DEG)):
        last = np.flatnonzero(paper_run.motion == m)[-1]
        speed = np.hypot(*paper_run.y[last, NQ : NQ + 2])
        # measured: 5.4e-8 .. 7.8e-8 m/s at the end of each 1 s motion; bar 10x the largest
        assert speed < 7.8e-7, (m + 1, speed)


def test_grasp_moves_object_down_and_compresses_symmetrically(paper_run):
    end1 = np.flatnonzero(paper_run.motion == 0)[-1]
    q = paper_run.y[end1, :NQ]
    assert q[model.Y_OBJ] < PARAMS.L
    assert q[model.DN_1] == pytest.approx(q[model.DN_2], rel=1e-9)
    assert 0.003 < q[model.DN_1] < PARAMS.a / 2


# ------------------------------------------------------------------------------ symmetry
@pytest.mark.parametrize("a_deg,b_deg", [(6.0, 6.0), (20.0, -10.0), (-7.0, 17.0)])
def test_default_model_is_mirror_symmetric(a_deg, b_deg):
    ab = run_setpoint_sequence(np.radians([[6, 6], [a_deg, b_deg]]), duration=0.4).y[-1]
    ba = run_setpoint_sequence(np.radians([[6, 6], [b_deg, a_deg]]), duration=0.4).y[-1]
    scale = 1e-9 * max(abs(ab[model.X_OBJ]), 1e-3)
    assert ab[model.X_OBJ] == pytest.approx(-ba[model.X_OBJ], abs=scale)
    assert ab[model.TH_OBJ] == pytest.approx(-ba[model.TH_OBJ], abs=1e-9 * max(abs(ab[2]), 1e-3))
    assert ab[model.Y_OBJ] == pytest.approx(ba[model.Y_OBJ], rel=1e-9)
    if a_deg == b_deg:
        assert abs(ab[model.TH_OBJ]) < 1e-12 and abs(ab[model.X_OBJ]) < 1e-12


def test_printed_cross_term_sign_breaks_the_symmetry():
    """docs/design.md: with the printed (-1)^i sign, set-points (6, 6) tilt the object."""
    printed = PARAMS.replace(cross_term="printed")
    y = run_setpoint_sequence(np.radians([[6, 6]]), printed, duration=0.5).y[-1]
    assert abs(math.degrees(y[model.TH_OBJ])) > 0.1


# -------------------------------------------------------------------------------- energy
def total_energy(y, prm, u, Kp):
    q, p = y[:NQ], y[NQ : 2 * NQ]
    spring = 0.5 * Kp * np.sum((q[model.TH_1 : model.TH_1 + 2] - u) ** 2)
    return 0.5 * p @ mass_matrix(prm) @ p + potential_energy(q, prm) + spring


def energy_history(params, y0, u_deg, T, every):
    prm = pack_params(params)
    u = np.radians(u_deg)
    y = y0.copy()
    E = [total_energy(y, prm, u, params.Kp)]
    for _ in range(round(T / (params.dt * every))):
        advance(y, u, prm, every)
        E.append(total_energy(y, prm, u, params.Kp))
    return np.array(E)


def test_damped_spring_driven_hand_never_gains_energy():
    """Kp only (Kd = Ki = 0), c_n = c_t = 300: E(t) is non-increasing up to round-off.

    Measured largest single-substep increase: 1.1e-15 J on E ~ 3.5 J (1 ulp ~ 4.4e-16 J).
    """
    params = PARAMS.replace(Kd=0.0, Ki=0.0)
    E = energy_history(params, model.initial_state(params), (6, 6), T=0.3, every=1)
    assert E[-1] < 0.5 * E[0]  # the contact damping really dissipates
    assert np.diff(E).max() <= 8 * np.finfo(float).eps * np.abs(E).max()


def test_undamped_energy_drift_is_fourth_order_in_dt():
    """c_n = c_t = 0, Kd = Ki = 0: energy is conserved up to the integration error.

    Measured max |E - E0| over 50 ms for dt = 1e-4 .. 1.25e-5 s: 2.5e-6, 3.7e-8, 1.6e-9,
    8.7e-11 J: pre-asymptotic at 1e-4 (alpha dt = 2), then ratios 23 and 19 (order 4.5, 4.2).
    """
    base = PARAMS.replace(Kd=0.0, Ki=0.0, c_n=0.0, c_t=0.0)
    y0 = grasp_state(0.3)
    devs = []
    for dt in (5e-5, 2.5e-5, 1.25e-5):
        E = energy_history(base.replace(dt=dt), y0, (8, 4), T=0.05, every=round(1e-4 / dt))
        devs.append(np.abs(E - E[0]).max())
    orders = np.log2(np.array(devs[:-1]) / np.array(devs[1:]))
    assert np.all(orders > 3.7), (devs, orders)


# ---------------------------------------------------------------------- kernel agreement
@pytest.mark.parametrize("u_deg", [(20.0, -10.0), (-7.0, 17.0)])
def test_compiled_kernel_matches_numpy_reference(u_deg):
    """1000 substeps (0.1 s) after a set-point step from a settled grasp.

    Errors are measured per block relative to the largest magnitude the block reaches in the
    run. One evaluation of the kernel's sparse Schur-complement solve agrees with the dense
    13x13 LU of the reference to ~1e-15 relative. Positions (q) and the PID integrals (z)
    then agree to <= 1e-12 relative (measured ~2e-15). Velocities (p) are the solution of a
    stiff system (Baumgarte alpha = 2e4/s, PID and contact modes up to ~1e4/s) whose
    accelerations are differences of O(1e5) terms; their round-off differences propagate to
    ~1e-11 of the peak velocity (measured 1.4e-11 .. 2e-11), so that block is held to 1e-10.
    """
    prm = pack_params(PARAMS)
    y0 = grasp_state(0.3)
    u = np.radians(u_deg)
    y_ref = y0.copy()
    y_ker = y0.copy()
    peak = np.abs(y0).copy()
    worst = np.zeros(NY)
    for _ in range(10):
        y_ref = advance_reference(y_ref, u, prm, 100)
        advance(y_ker, u, prm, 100)
        peak = np.maximum(peak, np.abs(y_ref))
        worst = np.maximum(worst, np.abs(y_ker - y_ref))
    rel = {
        name: worst[block].max() / peak[block].max()
        for name, block in (("q", slice(0, NQ)), ("p", slice(NQ, 2 * NQ)), ("z", slice(2 * NQ, NY)))
    }
    assert rel["q"] <= 1e-12 and rel["z"] <= 1e-12, rel
    assert rel["p"] <= 1e-10, rel


def test_batched_kernel_matches_single_kernel_with_per_system_params():
    rng = np.random.default_rng(0)
    N = 6
    params = [PARAMS.replace(E=PARAMS.E * rng.uniform(0.8, 1.2), M_obj=rng.uniform(0.2, 0.4))
              for _ in range(N)]
    PRM = np.stack([pack_params(p) for p in params])
    Y = np.stack([grasp_state(0.05, params=p) for p in params])
    U = np.radians(np.array(PAPER_MOTIONS_DEG[1:7]))  # grasp-keeping set-points
    Y_single = Y.copy()
    DIAG, FLAGS = kernel.advance_batch_py(Y, U, PRM, 500)
    for s in range(N):
        d = advance(Y_single[s], U[s], PRM[s], 500)
        # both kernels inline the same model.csm_terms, compiled without fast-math
        # (model._FASTMATH): the lane-batched arithmetic is the scalar one, bit for bit
        np.testing.assert_array_equal(DIAG[s], d)
    assert np.all(FLAGS == 0)
    np.testing.assert_array_equal(Y, Y_single)


# -------------------------------------------------------------------- invalid situations
@pytest.mark.parametrize("bad", [[np.nan, 0.1], [0.1, np.inf], [0.1, 0.2, 0.3]])
def test_bad_setpoints_raise_value_error(bad):
    physics = HandPhysics()
    with pytest.raises(ValueError, match="setpoint"):
        physics.step(bad, 10)


@pytest.mark.filterwarnings("ignore:RK4 step")
def test_divergence_raises_physics_error_and_is_flagged():
    # RK4 at dt = 1 ms is unstable for alpha = 2e4 (alpha dt = 20 > 2.8)
    physics = HandPhysics(PARAMS.replace(dt=1e-3))
    with pytest.raises(PhysicsError) as info:
        for _ in range(100):
            physics.step(np.radians([6, 6]), 10)
    assert info.value.flags & (kernel.FLAG_NONFINITE | kernel.FLAG_CONSTRAINT)
    status = HandPhysics(PARAMS.replace(dt=1e-3)).step(np.radians([6, 6]), 1000, strict=False)
    assert status.fatal and status.substeps < 1000


def test_default_parameters_are_inside_rk4_stability():
    from softhand_env.physics import check_rk4_stability, rk4_stability_margins

    assert check_rk4_stability(PARAMS) == []
    assert rk4_stability_margins(PARAMS)["holonomic (alpha)"] == pytest.approx(2.0)


def test_stiff_bending_beyond_rk4_stability_warns_and_is_flagged():
    """bending = 1e5 puts the d_t mode at |lambda| dt ~ 7: warned up front, and the run that
    follows is stopped by a fatal flag rather than returning a wrong state silently."""
    stiff = PARAMS.replace(bending=1e5, g=0.0)
    with pytest.warns(RuntimeWarning, match="bending"):
        physics = HandPhysics(stiff)
    fatal = False
    for k in range(60):
        status = physics.step(np.radians([0.1 * (k + 1)] * 2), 100, strict=False)
        if status.fatal:
            fatal = True
            break
    assert fatal


def test_opening_the_fingers_loses_the_grasp():
    physics = HandPhysics()
    physics.step(np.radians([6, 6]), 3000)
    status = physics.step(np.radians([-20, -20]), 5000)
    assert status.flags & kernel.FLAG_LOST and "grasp_lost" in status.reasons
    assert status.substeps < 5000
    assert np.all(np.isfinite(physics.get_state()))


def test_readouts_are_copies():
    physics = HandPhysics()
    pose = physics.object_pose
    pose[:] = 99.0
    assert physics.object_pose[0] == 0.0
    state = physics.get_state()
    state[0] = 1.0
    assert physics.get_state()[0] == 0.0


def test_reset_sets_setpoints_to_the_finger_angles():
    physics = HandPhysics()
    physics.step(np.radians([6, 6]), 100)
    state = physics.get_state()
    physics.reset(state)
    np.testing.assert_array_equal(physics.setpoint, state[model.TH_1 : model.TH_1 + 2])


def test_batched_kernel_skips_flagged_systems():
    prm = pack_params(PARAMS)
    Y = np.stack([model.initial_state(PARAMS)] * 3)
    Y0 = Y.copy()
    DIAG = np.zeros((3, 2))
    FLAGS = np.array([0, kernel.FLAG_SKIP, 0], dtype=np.int64)
    kernel.advance_batch(Y, np.radians([[6.0, 6.0]] * 3), np.tile(prm, (3, 1)), 50, 1e-3, DIAG,
                         FLAGS)
    np.testing.assert_array_equal(Y[1], Y0[1])
    assert FLAGS[1] == kernel.FLAG_SKIP and FLAGS[0] == 0
    assert not np.array_equal(Y[0], Y0[0])
