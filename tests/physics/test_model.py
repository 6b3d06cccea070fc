"""Verification of the chapter-5 model terms independently of their derivation.

Every term in softhand_env.physics.model is checked against something it was not built from:
finite differences of the constraint and energy functions, the printed Eq 5.25-5.30
(where not misprinted), and the geometric definition of the rolling constraint.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from softhand_env.physics import model
from softhand_env.physics.model import (
    DN_1,
    DT_1,
    NQ,
    TH_1,
    TH_OBJ,
    X_OBJ,
    Y_OBJ,
    constraint_terms,
    elastic_energy,
    pack_params,
    potential_energy,
    potential_forces,
)
from softhand_env.physics.params import HandParams

PARAMS = HandParams()
PRM = pack_params(PARAMS)


def random_states(n: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Grasp-like states: angles within +-25 deg, d_n in (1, 8) mm, d_t within +-2 mm."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        q = np.empty(NQ)
        q[X_OBJ] = rng.uniform(-0.02, 0.02)
        q[Y_OBJ] = PARAMS.L + rng.uniform(-0.01, 0.01)
        q[TH_OBJ] = rng.uniform(-0.3, 0.3)
        q[TH_1 : TH_1 + 2] = rng.uniform(-0.4, 0.4, 2)
        q[DN_1 : DN_1 + 2] = rng.uniform(1e-3, 8e-3, 2)
        q[DT_1 : DT_1 + 2] = rng.uniform(-2e-3, 2e-3, 2)
        p = rng.normal(size=NQ) * np.array([0.05, 0.05, 1, 2, 2, 0.01, 0.01, 0.01, 0.01])
        out.append((q, p))
    return out


def terms(q, p, prm=PRM):
    Phi, b, C = np.empty((4, NQ)), np.empty(4), np.empty(2)
    constraint_terms(q, p, prm, Phi, b, C)
    return Phi, b, C


def fingertip_centre(q, i, prm=PRM):
    """Eqs 5.7-5.8 written directly (i = 1 right, 2 left)."""
    L, W, dfi = prm[model.P_L], prm[model.P_WFI], prm[model.P_DFI]
    th = q[TH_1 + i - 1]
    s = (-1) ** i
    return (
        (-1) ** (i + 1) * W + s * L * math.sin(th) + s * dfi * math.cos(th),
        L * math.cos(th) - dfi * math.sin(th),
    )


def gq(q, i):
    """Eq 5.11: GQ_i = -(x - O_ix) sin(theta_obj) + (y - O_iy) cos(theta_obj)."""
    ox, oy = fingertip_centre(q, i)
    return -(q[X_OBJ] - ox) * math.sin(q[TH_OBJ]) + (q[Y_OBJ] - oy) * math.cos(q[TH_OBJ])


# Central differences with step 1e-6 on functions of O(1e-2..1) magnitude: truncation
# O(h^2 f''') ~ 1e-12, round-off O(eps f / h) ~ 1e-10 relative; 1e-7 leaves margin.
FD_STEP = 1e-6
FD_RTOL = 1e-7


@pytest.mark.parametrize("q,p", random_states(20))
def test_holonomic_jacobian_matches_finite_differences(q, p):
    Phi, _, _ = terms(q, p)
    J = np.empty((2, NQ))
    for j in range(NQ):
        e = np.zeros(NQ)
        e[j] = FD_STEP
        J[:, j] = (terms(q + e, p)[2] - terms(q - e, p)[2]) / (2 * FD_STEP)
    np.testing.assert_allclose(Phi[:2], J, rtol=FD_RTOL, atol=FD_RTOL * np.abs(J).max())


@pytest.mark.parametrize("q,p", random_states(20, seed=1))
def test_velocity_terms_are_time_derivative_of_phi(q, p):
    """b = (dPhi/dt) p along the motion q(t) = q + p t."""
    _, b, _ = terms(q, p)
    dPhi = (terms(q + FD_STEP * p, p)[0] - terms(q - FD_STEP * p, p)[0]) / (2 * FD_STEP)
    np.testing.assert_allclose(b, dPhi @ p, rtol=FD_RTOL, atol=1e-7 * np.abs(dPhi @ p).max())


@pytest.mark.parametrize("q,p", random_states(10, seed=2))
def test_rolling_constraint_matches_its_geometric_definition(q, p):
    """C^N_i = d(GQ_i)/dt - ds_i/dt + dd_ti/dt with ds_i/dt = -(a - d_ni)(w_i + (-1)^i w_obj)."""
    Phi, _, _ = terms(q, p)
    a = PARAMS.a
    for i in (1, 2):
        dgq = (gq(q + FD_STEP * p, i) - gq(q - FD_STEP * p, i)) / (2 * FD_STEP)
        sdot = -(a - q[DN_1 + i - 1]) * (p[TH_1 + i - 1] + (-1) ** i * p[TH_OBJ])
        expected = dgq - sdot + p[DT_1 + i - 1]
        assert Phi[1 + i] @ p == pytest.approx(expected, rel=1e-7, abs=1e-9)


@pytest.mark.parametrize("q,p", random_states(10, seed=3))
def test_constraint_matrix_matches_printed_eq_5_25(q, p):
    """Eq 5.25 with A_ci, B_ci, E_ci, F_ci of Eqs 5.26-5.29 (theta_r in 5.29 read as theta_i)."""
    Phi, _, _ = terms(q, p)
    L, dfi, a = PARAMS.L, PARAMS.d_fi, PARAMS.a
    x, y, to = q[X_OBJ], q[Y_OBJ], q[TH_OBJ]
    for i in (1, 2):
        th = q[TH_1 + i - 1]
        ox, oy = fingertip_centre(q, i)
        tp = th + (-1) ** i * to
        A = (-1) ** (i + 1) * (x - ox) * math.sin(to) + (-1) ** i * (y - oy) * math.cos(to)
        B = -L * math.cos(tp) + dfi * math.sin(tp)
        E = -(x - ox) * math.cos(to) - (y - oy) * math.sin(to) + (-1) ** i * (a - q[DN_1 + i - 1])
        F = L * math.sin(tp) + dfi * math.cos(tp) + (a - q[DN_1 + i - 1])
        h = np.zeros(NQ)
        h[[X_OBJ, Y_OBJ, TH_OBJ, TH_1 + i - 1, DN_1 + i - 1]] = [
            (-1) ** i * math.cos(to), (-1) ** i * math.sin(to), A, B, 1.0,
        ]
        n = np.zeros(NQ)
        n[[X_OBJ, Y_OBJ, TH_OBJ, TH_1 + i - 1, DT_1 + i - 1]] = [
            -math.sin(to), math.cos(to), E, F, 1.0,
        ]
        np.testing.assert_allclose(Phi[i - 1], h, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(Phi[1 + i], n, rtol=1e-12, atol=1e-15)


def test_e_ci_is_constant_on_the_constraint_manifold():
    """Eq 5.30: with C^H = 0, E_ci = -(-1)^i W_obj / 2."""
    for q, p in random_states(10, seed=4):
        # project onto C^H = 0 by adjusting d_n (C^H is linear in d_n with coefficient 1)
        _, _, C = terms(q, p)
        q = q.copy()
        q[DN_1 : DN_1 + 2] -= C
        Phi, _, C = terms(q, p)
        assert np.abs(C).max() < 1e-15
        for i in (1, 2):
            assert Phi[1 + i, TH_OBJ] == pytest.approx(-((-1) ** i) * PARAMS.W_obj / 2, abs=1e-15)


@pytest.mark.parametrize("cross_term", ["uniform", "printed"])
@pytest.mark.parametrize("q,p", random_states(10, seed=5))
def test_forces_are_negative_energy_gradient_plus_damping(q, p, cross_term):
    prm = pack_params(PARAMS.replace(cross_term=cross_term, bending=2.5))
    f = np.empty(NQ)
    potential_forces(q, p, prm, f)
    grad = np.empty(NQ)
    for j in range(NQ):
        e = np.zeros(NQ)
        e[j] = FD_STEP * max(1e-3, abs(q[j]))
        grad[j] = (potential_energy(q + e, prm) - potential_energy(q - e, prm)) / (2 * e[j])
    damping = np.zeros(NQ)
    damping[DN_1 : DN_1 + 2] = PARAMS.c_n * p[DN_1 : DN_1 + 2]
    damping[DT_1 : DT_1 + 2] = PARAMS.c_t * p[DT_1 : DT_1 + 2]
    np.testing.assert_allclose(f, -grad - damping, rtol=1e-6, atol=1e-7 * np.abs(grad).max())


def test_elastic_energy_is_eq_5_5():
    """Eq 5.5 written out with theta_pi = theta_i + (-1)^i theta_obj, both sign options."""
    for q, _ in random_states(5, seed=6):
        for cross_term, signs in (("uniform", (-1, -1)), ("printed", (-1, 1))):
            prm = pack_params(PARAMS.replace(cross_term=cross_term))
            total = 0.0
            for i in (1, 2):
                tp = q[TH_1 + i - 1] + (-1) ** i * q[TH_OBJ]
                dn, dt = q[DN_1 + i - 1], q[DT_1 + i - 1]
                total += math.pi * PARAMS.E * (
                    dn**3 / (3 * math.cos(tp) ** 2)
                    + signs[i - 1] * dn**2 * dt * math.tan(tp)
                    + dn * dt**2
                )
            assert elastic_energy(q, prm) == pytest.approx(total, rel=1e-13)


def test_initial_state_is_point_contact_on_both_constraints():
    y = model.initial_state(PARAMS)
    Phi, _, C = terms(y[:NQ], y[NQ : 2 * NQ])
    assert np.abs(C).max() < 1e-15
    assert y[Y_OBJ] == pytest.approx(PARAMS.L)
    assert model.initial_finger_angle(PARAMS) == pytest.approx(0.0, abs=1e-15)
    # a narrower object: fingers start rotated inward, still at point contact
    narrow = PARAMS.replace(W_obj=0.040)
    y = model.initial_state(narrow)
    _, _, C = terms(y[:NQ], y[NQ : 2 * NQ], pack_params(narrow))
    assert y[TH_1] > 0 and np.abs(C).max() < 1e-15
