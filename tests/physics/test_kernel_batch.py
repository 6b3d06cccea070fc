"""The batched (lane / SIMD) kernel against the single-system kernel, system by system.

:func:`kernel.advance_batch` integrates blocks of systems in structure-of-arrays lanes; each
system must come out as :func:`kernel.advance` leaves it: the same flags (including the
substep of a mid-call fatal stop), state and diagnostics to round-off, skipped and
pre-flagged systems untouched. Batch sizes cover the one-by-one path (N <= 4), half blocks,
full blocks and partial last blocks.
"""

from __future__ import annotations

import math
import platform

import numpy as np
import pytest

from softhand_env.physics import kernel, model
from softhand_env.physics.model import DN_1, NQ, NY, TH_1, pack_params
from softhand_env.physics.params import HandParams

PARAMS = HandParams()
CH_LIMIT = kernel.CH_LIMIT
SIZES = [1, 3, 5, 8, 13, 37, 70]  # one by one, half blocks, full blocks + a partial one


def settled(params: HandParams, substeps: int = 300) -> np.ndarray:
    """The grasp after ``substeps`` at 6 deg set-points (the initial contact state if the
    grasp does not survive them, as for a light object on stiff fingertips)."""
    y = model.initial_state(params)
    flags, _ = kernel.advance(y, np.radians([6.0, 6.0]), pack_params(params), substeps,
                              CH_LIMIT, np.zeros(2))
    return y if flags == 0 else model.initial_state(params)


def random_batch(N: int, seed: int):
    """Heterogeneous hands (mass, stiffness, gains, inertia, time step), each settled in its
    grasp, with set-points that keep some grasps and break others mid-call."""
    rng = np.random.default_rng(seed)
    params = [
        PARAMS.replace(
            E=PARAMS.E * rng.uniform(0.8, 1.2),
            M_obj=rng.uniform(0.2, 0.4),
            I_obj=PARAMS.I_obj * rng.uniform(0.8, 1.2),
            Kp=PARAMS.Kp * rng.uniform(0.8, 1.2),
            Kd=PARAMS.Kd * rng.uniform(0.8, 1.2),
            c_n=PARAMS.c_n * rng.uniform(0.8, 1.2),
            dt=float(rng.choice([1e-4, 5e-5])),
        )
        for _ in range(N)
    ]
    PRM = np.stack([pack_params(p) for p in params])
    Y = np.stack([settled(p, int(rng.integers(100, 400))) for p in params])
    U = np.radians(rng.uniform(-20.0, 30.0, (N, 2)))
    return Y, U, PRM


def _outputs(Y, FLAGS_IN):
    """Fresh copies of the state and input flags, and a DIAG of -1 (untouched marker)."""
    N = Y.shape[0]
    FLAGS = np.zeros(N, dtype=np.int64) if FLAGS_IN is None else FLAGS_IN.copy()
    return Y.copy(), np.full((N, kernel.N_STEP_DIAG), -1.0), FLAGS


def run_single(Y, U, PRM, n, FLAGS_IN=None, ch_limit=CH_LIMIT):
    """What advance_batch must produce, from kernel.advance system by system."""
    Y, DIAG, FLAGS = _outputs(Y, FLAGS_IN)
    for s in range(Y.shape[0]):
        if FLAGS[s] & (kernel.FATAL_FLAGS | kernel.FLAG_SKIP):
            continue
        d = np.zeros(kernel.N_STEP_DIAG)
        FLAGS[s], _ = kernel.advance(Y[s], U[s], PRM[s], n, ch_limit, d)
        DIAG[s] = d
    return Y, DIAG, FLAGS


def run_batch(Y, U, PRM, n, FLAGS_IN=None, ch_limit=CH_LIMIT, parallel=None):
    Y, DIAG, FLAGS = _outputs(Y, FLAGS_IN)
    kernel.advance_batch(Y, U, PRM, n, ch_limit, DIAG, FLAGS, parallel)
    return Y, DIAG, FLAGS


def assert_same(batch, single):
    """Bit for bit: state (NaN where NaN), diag (residuals and contact impulses) and flags.

    Both kernels evaluate the same model source (model.csm_terms) and the same RK4
    combinations in strict IEEE arithmetic (model._FASTMATH), so vectorising across systems
    changes no rounding. Should fast-math ever be re-enabled, the bar becomes round-off
    (test_dynamics: q <= 1e-13, p <= 1e-10 relative, diag 1e-14) and flags can differ where a
    grasp is lost within round-off of the threshold.
    """
    Yb, Db, Fb = batch
    Ys, Ds, Fs = single
    np.testing.assert_array_equal(Fb, Fs)
    np.testing.assert_array_equal(Yb, Ys)  # NaN == NaN here
    np.testing.assert_array_equal(Db, Ds)


@pytest.mark.parametrize("N", SIZES)
def test_heterogeneous_batch_matches_single_kernel(N):
    Y, U, PRM = random_batch(N, seed=N)
    single = run_single(Y, U, PRM, 400)
    assert_same(run_batch(Y, U, PRM, 400), single)


@pytest.mark.parametrize("parallel", [False, True])
def test_serial_and_parallel_blocks_match_single_kernel(parallel):
    """The blocks on the calling thread or over numba's threads: the same numbers (what lets
    HandPhysics choose the mode by time)."""
    Y, U, PRM = random_batch(37, seed=3)
    assert_same(run_batch(Y, U, PRM, 400, parallel=parallel), run_single(Y, U, PRM, 400))


def test_mix_of_kept_and_broken_grasps_stops_each_system_at_its_own_substep():
    Y, U, PRM = random_batch(70, seed=1)
    single = run_single(Y, U, PRM, 400)
    flags = single[2]
    # the random set-points do both: grasps kept and grasps lost or over-compressed mid-call
    assert np.any(flags == 0)
    assert np.any(flags & (kernel.FLAG_LOST | kernel.FLAG_OVERCOMPRESSED))
    assert_same(run_batch(Y, U, PRM, 400), single)


@pytest.mark.parametrize("N", [5, 8, 21, 70])
def test_divergent_systems_stop_at_the_same_substep(N):
    """dt = 1 ms is outside RK4 stability for alpha = 2e4: those systems blow up (a fatal flag:
    non-finite, or d_n leaving [0, a) first) at their own substep; their lane-mates carry on
    unaffected."""
    rng = np.random.default_rng(N)
    params = [PARAMS.replace(dt=1e-3) if rng.random() < 0.4 else PARAMS for _ in range(N)]
    params[0] = PARAMS.replace(dt=1e-3)
    PRM = np.stack([pack_params(p) for p in params])
    Y = np.stack([settled(PARAMS, 200)] * N)
    Y[:, NQ:] += rng.normal(0.0, 1e-3, (N, NY - NQ))  # distinct trajectories
    U = np.radians(rng.uniform(0.0, 12.0, (N, 2)))
    single = run_single(Y, U, PRM, 300)
    unstable = PRM[:, model.P_DT] == 1e-3
    assert np.all(single[2][unstable] & kernel.FATAL_FLAGS)
    assert_same(run_batch(Y, U, PRM, 300), single)


def test_nonfinite_and_out_of_range_initial_states():
    """A NaN state, d_n < 0 and d_n >= a on entry (flags 0): stopped after one substep like the
    single kernel, without disturbing the other lanes of their block."""
    N = 11
    Y = np.stack([settled(PARAMS, 200)] * N)
    Y[2, TH_1] = np.nan
    Y[5, DN_1] = -1e-4
    Y[7, DN_1 + 1] = PARAMS.a
    Y[9, NQ] = np.inf
    PRM = np.tile(pack_params(PARAMS), (N, 1))
    U = np.radians(np.tile([8.0, 8.0], (N, 1)))
    single = run_single(Y, U, PRM, 200)
    assert single[2][2] == kernel.FLAG_NONFINITE and single[2][9] == kernel.FLAG_NONFINITE
    assert single[2][5] & kernel.FLAG_LOST and single[2][7] & kernel.FLAG_OVERCOMPRESSED
    assert_same(run_batch(Y, U, PRM, 200), single)


@pytest.mark.parametrize("N", [1, 3, 6, 20, 70])
def test_skipped_and_preflagged_systems_are_left_alone(N):
    Y, U, PRM = random_batch(N, seed=100 + N)
    rng = np.random.default_rng(N)
    FLAGS = rng.choice(
        [0, 0, 0, kernel.FLAG_SKIP, kernel.FLAG_LOST, kernel.FLAG_NONFINITE | kernel.FLAG_BASE,
         kernel.FLAG_BASE],
        N,
    ).astype(np.int64)
    FLAGS[0] = kernel.FLAG_SKIP
    single = run_single(Y, U, PRM, 300, FLAGS)
    batch = run_batch(Y, U, PRM, 300, FLAGS)
    assert_same(batch, single)
    left = (FLAGS & (kernel.FATAL_FLAGS | kernel.FLAG_SKIP)) != 0
    np.testing.assert_array_equal(batch[0][left], Y[left])
    np.testing.assert_array_equal(batch[1][left], -1.0)  # DIAG rows not written
    np.testing.assert_array_equal(batch[2][left], FLAGS[left])


def test_all_systems_skipped_is_a_no_op():
    Y, U, PRM = random_batch(9, seed=3)
    FLAGS = np.full(9, kernel.FLAG_SKIP, dtype=np.int64)
    Yb, Db, Fb = run_batch(Y, U, PRM, 100, FLAGS)
    np.testing.assert_array_equal(Yb, Y)
    np.testing.assert_array_equal(Db, -1.0)
    np.testing.assert_array_equal(Fb, FLAGS)


@pytest.mark.parametrize("n", [0, 1, 7])
def test_few_substeps(n):
    """n = 0 only evaluates the final-state residuals and flags."""
    Y, U, PRM = random_batch(19, seed=7)
    assert_same(run_batch(Y, U, PRM, n), run_single(Y, U, PRM, n))


def test_constraint_limit_is_applied_at_the_end_of_the_call():
    Y, U, PRM = random_batch(24, seed=11)
    _, diag, flags = run_single(Y, U, PRM, 200)
    limit = float(np.median(diag[flags == 0, 0]))  # half of the kept grasps exceed it
    single = run_single(Y, U, PRM, 200, ch_limit=limit)
    assert np.any(single[2] & kernel.FLAG_CONSTRAINT) and np.any(single[2] == 0)
    assert_same(run_batch(Y, U, PRM, 200, ch_limit=limit), single)


def test_broadcast_parameter_view():
    N = 20
    Y = np.stack([settled(PARAMS, 200)] * N)
    U = np.radians(np.random.default_rng(0).uniform(0.0, 15.0, (N, 2)))
    prm = pack_params(PARAMS)
    PRM = np.broadcast_to(prm, (N, prm.size))
    assert PRM.strides[0] == 0
    assert_same(run_batch(Y, U, PRM, 200), run_single(Y, U, np.tile(prm, (N, 1)), 200))


def test_repeated_calls_continue_like_the_single_kernel():
    """The vector env calls the kernel once per control step: 10 calls of 200 substeps."""
    Y, U, PRM = random_batch(40, seed=5)
    Yb, Ys = Y.copy(), Y.copy()
    Fb = np.zeros(40, dtype=np.int64)
    Fs = np.zeros(40, dtype=np.int64)
    for _ in range(10):
        Fb[:] = np.where(Fb & kernel.FATAL_FLAGS, Fb, 0)
        Fs[:] = np.where(Fs & kernel.FATAL_FLAGS, Fs, 0)
        Yb, Db, Fb = run_batch(Yb, U, PRM, 200, Fb)
        Ys, Ds, Fs = run_single(Ys, U, PRM, 200, Fs)
        # diag of systems stopped in an earlier call is not rewritten: compare the rest
        fresh = Ds[:, 0] >= 0
        assert_same((Yb, np.where(fresh[:, None], Db, -1.0), Fb),
                    (Ys, np.where(fresh[:, None], Ds, -1.0), Fs))


# ------------------------------------------------------------------------ building blocks
def test_sincos_agrees_with_libm():
    rng = np.random.default_rng(0)
    for r in (1e-3, 0.5, math.pi, 20.0, 1e4):
        x = rng.uniform(-r, r, 20000)
        sc = np.array([model.sincos(v) for v in x])
        for got, ref in ((sc[:, 0], np.sin(x)), (sc[:, 1], np.cos(x))):
            ulps = np.abs(got - ref) / np.spacing(np.abs(ref))
            assert ulps.max() <= 2.0, (r, ulps.max())
    assert model.sincos(0.0) == (0.0, 1.0)
    for bad in (np.nan, np.inf, -np.inf):
        assert all(math.isnan(v) for v in model.sincos(bad))


def test_lane_rhs_matches_csm_rhs():
    """_rhs_lanes (tuples from the structure-of-arrays block, vectorised) and csm_rhs (arrays,
    scalar) evaluate the same model source to the same bits."""
    L = kernel.LANES
    Y, U, PRM = random_batch(L, seed=2)
    Yl = np.ascontiguousarray(Y.T).ravel()
    Pl = np.ascontiguousarray(np.hstack([PRM, U]).T).ravel()
    Kl = np.zeros(kernel._NK * L)
    kernel._rhs_lanes(Yl, Pl, Kl, L)
    Kl = Kl.reshape(kernel._NK, L).T
    for s in range(L):
        dy = np.zeros(NY)
        diag = np.zeros(model.N_DIAG)
        model.csm_rhs(Y[s], U[s], PRM[s], dy, diag)
        np.testing.assert_array_equal(Kl[s, :NY], dy)
        np.testing.assert_array_equal(Kl[s, NY : NY + 4], diag[:4])  # C^H, C^N
        np.testing.assert_array_equal(Kl[s, NY + 4 :], diag[6:10])  # lambda_H, lambda_N


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 SIMD check")
def test_lane_rhs_is_vectorised():
    """LLVM must vectorise the loop over lanes (packed double arithmetic on ymm/zmm registers):
    a call it cannot inline (e.g. libm sin) or a loop it judges too small to check for
    aliasing silently falls back to scalar code at a quarter of the speed."""
    from numba import njit

    fn = njit(kernel._rhs_lanes.py_func, error_model="numpy", fastmath=model._FASTMATH)
    L = kernel.LANES
    fn(np.full(NY * L, 0.1), np.ones(kernel._NPU * L), np.zeros(kernel._NK * L), L)
    asm = fn.inspect_asm(fn.signatures[0])
    if "avx2" not in open("/proc/cpuinfo").read():
        pytest.skip("no AVX2")
    packed = [ln for ln in asm.splitlines()
              if ln.split() and ln.split()[0] in ("vmulpd", "vaddpd", "vsubpd", "vdivpd")
              and ("ymm" in ln or "zmm" in ln)]
    assert len(packed) > 200, len(packed)
