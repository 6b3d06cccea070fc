"""Tests of the soft-fingertip contact models (softhand_env.physics.contact, chapters 2, 3 and Eq
5.4).

Tolerances state the measured error and why the margin is what it is.  Independent references
(used to check the numerical integrals, not the closed forms against themselves):

* ``_semi_analytic_reference``: Eqs 2.3/2.8/2.12 in Cartesian ``(x, y)`` over the region of
  Eqs 2.4-2.5, cut at the base line ``x = (a - d) / sin(theta_p)``, with the inner ``x``
  integral in closed form (arcsin, square roots) and the outer one by scipy ``quad``; it
  handles the 1/L singularity at the corner.
* ``_cartesian_reference``: scipy ``quad`` nested in ``(x, y)`` for any bounded integrand (the
  nonlinear spring laws).
* ``_axisymmetric_reference``: at ``theta_p = 0`` the integrals are 1-D in ``r``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate, optimize

from softhand_env.physics import contact as c

A = 0.020  # fingertip radius of the experiments, m
E2 = c.E_CH2
MM, DEG = 1e-3, math.pi / 180

# --------------------------------------------------------------------------------------------
# independent references
# --------------------------------------------------------------------------------------------


def _truncated_region(d, theta, a):
    """y-limits ``x in [lo(y), hi(y)]`` of the truncated ellipse, ``a_c`` and the corner y."""
    a_c = math.sqrt(a * a - (a - d) ** 2)
    s, co, si = (a - d) * math.sin(theta), math.cos(theta), math.sin(theta)
    x_cut = (a - d) / si if si > 0 else math.inf

    def limits(y):
        half = math.sqrt(max(a_c * a_c - y * y, 0.0))
        return s - co * half, min(s + co * half, x_cut)

    corner = None if x_cut - s >= co * a_c else [math.sqrt(a_c**2 - ((x_cut - s) / co) ** 2)]
    return limits, a_c, corner


def _outer(inner, a_c, corner):
    return 2 * integrate.quad(inner, 0, a_c, epsabs=0, epsrel=1e-12, limit=400, points=corner)[0]


def _cartesian_reference(strain_density, d, theta, a=A):
    """int int strain_density(PQ, L) dx dy over the truncated ellipse (scipy quad in x, y)."""
    limits, a_c, corner = _truncated_region(d, theta, a)
    co, si = math.cos(theta), math.sin(theta)

    def inner(y):
        lo, hi = limits(y)
        if hi <= lo:
            return 0.0

        def g(x):
            length = math.sqrt(max(a * a - x * x - y * y, 0.0))
            return strain_density(length - (a - d - x * si) / co, length)

        return integrate.quad(g, lo, hi, epsabs=0, epsrel=1e-12, limit=200)[0]

    return _outer(inner, a_c, corner)


def _semi_analytic_reference(quantity, d, theta, a=A):
    """K/E, F/E or P/E (Eqs 2.3, 2.8, 2.12) with the inner x integral done in closed form.

    On a line y = const, L = sqrt(X^2 - x^2) and z_P = alpha - beta x, so the integrands
    1/L, PQ/L = 1 - z_P/L and PQ^2/(2L) = (L - 2 z_P + z_P^2/L)/2 integrate with arcsin and
    square roots; only the outer y integral is numerical (quad, corner as breakpoint).
    """
    limits, a_c, corner = _truncated_region(d, theta, a)
    alpha, beta = (a - d) / math.cos(theta), math.tan(theta)

    def antiderivative(x, X):
        u, S = math.asin(max(-1.0, min(1.0, x / X))), math.sqrt(max(X * X - x * x, 0.0))
        i0, i1, i2 = u, -S, 0.5 * (X * X * u - x * S)  # int x^k / L dx, k = 0, 1, 2
        z_over_l = alpha * i0 - beta * i1
        if quantity == "K":
            return i0
        if quantity == "F":
            return x - z_over_l
        length = 0.5 * (x * S + X * X * u)  # int L dx
        z = alpha * x - 0.5 * beta * x * x  # int z_P dx
        return 0.5 * (length - 2 * z + alpha**2 * i0 - 2 * alpha * beta * i1 + beta**2 * i2)

    def inner(y):
        (lo, hi), X = limits(y), math.sqrt(a * a - y * y)
        return antiderivative(hi, X) - antiderivative(lo, X) if hi > lo else 0.0

    return _outer(inner, a_c, corner)


def _axisymmetric_reference(spring_stress, d, a=A):
    """int spring_stress(eps) dS at theta_p = 0: 2 pi int_0^a_c f(eps(r)) r dr (Eq 3.6)."""

    def g(r):
        return 2 * math.pi * r * spring_stress(1 - (a - d) / math.sqrt(a * a - r * r))

    a_c = math.sqrt(a * a - (a - d) ** 2)
    return integrate.quad(g, 0, a_c, epsabs=0, epsrel=1e-13, limit=200)[0]


def _stress_pa(eps):
    # Eq 3.3 evaluated directly in % and kPa (independent of the module's coefficient scaling)
    e = 100 * eps
    return 1e3 * sum(a_i * e**i for i, a_i in enumerate(c.STRESS_FIT_KPA_PERCENT, start=1))


def _tangent_pa(eps):
    e = 100 * eps
    return 1e5 * sum(i * a_i * e ** (i - 1) for i, a_i in enumerate(c.STRESS_FIT_KPA_PERCENT, 1))


def _rel(x, ref):
    return np.max(np.abs(np.asarray(x) / np.asarray(ref) - 1))


# --------------------------------------------------------------------------------------------
# chapter 2: numeric integrals vs closed forms
# --------------------------------------------------------------------------------------------

D_GRID = np.linspace(0.5, 8.0, 16)[:, None] * MM
TH_GRID = np.linspace(0.0, 30.0, 31)[None, :] * DEG


@pytest.mark.parametrize(
    "numeric, closed",
    [
        (c.stiffness_numeric, lambda d, th: c.stiffness(d, E2) + 0 * th),
        (c.normal_force_numeric, lambda d, th: c.normal_force(d, th, E2)),
        (c.potential_energy_numeric, lambda d, th: c.potential_energy(d, th, E2)),
    ],
    ids=["K", "F", "P"],
)
def test_numeric_matches_closed_form_on_paper_range(numeric, closed):
    # Figs 2.6/2.7 range, all inside the bound for a = 20 mm (bound >= 36.9 deg).
    # Measured max rel. error 4e-15 (K, F, P); 1e-8 is the acceptance target.
    got = numeric(D_GRID, TH_GRID, E2, A)
    assert got.shape == (16, 31)
    assert _rel(got, closed(D_GRID, TH_GRID)) <= 1e-8


def test_stiffness_independent_of_angle():
    # Assumption 3 of the text; numerically the spread is at round-off level (measured 4e-16).
    K = c.stiffness_numeric(D_GRID, np.linspace(-30, 30, 25) * DEG, E2, A)
    assert np.all(np.ptp(K, axis=1) <= 1e-12 * K[:, 0])


def test_force_has_local_minimum_at_zero_angle():
    # Fig 2.11: symmetric angle grid; F(theta) = F(-theta) and F grows with |theta|.
    thetas = np.linspace(-30, 30, 25) * DEG
    F = c.normal_force_numeric(np.arange(1, 9)[:, None] * MM, thetas, E2, A)
    assert np.all(np.argmin(F, axis=1) == 12)  # thetas[12] == 0
    np.testing.assert_allclose(F, F[:, ::-1], rtol=1e-13)  # measured 0 (|theta_p| is used)
    assert np.all(np.diff(F[:, 12:], axis=1) > 0)


def test_energy_normal_contact_and_appendix_d():
    d = np.array([2.0, 4.0, 6.0]) * MM
    # Eq D.1: measured rel. error 3e-15
    assert _rel(c.potential_energy_numeric(d, 0.0, E2, A), math.pi * E2 * d**3 / 3) <= 1e-12
    # Eq D.2: dP/dd = F at theta_p = 0, and (Appendix D) dP/dd = F / cos(theta_p) otherwise.
    # Central difference with h = 0.1 um: truncation h^2/(3 d^2) = 8e-10 at d = 2 mm, plus
    # quadrature noise (~4e-15) amplified by d/h <= 6e4; measured 8.3e-10, tolerance 1e-8.
    h = 1e-7
    for theta in (0.0, 20 * DEG):
        dP = (
            c.potential_energy_numeric(d + h, theta, E2, A)
            - c.potential_energy_numeric(d - h, theta, E2, A)
        ) / (2 * h)
        F = c.normal_force_numeric(d, theta, E2, A)
        assert _rel(dP * math.cos(theta), F) <= 1e-8


def test_closed_form_values():
    # hand-computed: d = 4 mm, theta = 30 deg, E = 0.2032 MPa
    d, th = 4 * MM, 30 * DEG
    assert c.stiffness(d, E2) == pytest.approx(5106.9730, rel=1e-7)
    assert c.normal_force(d, th, E2) == pytest.approx(11.794049, rel=1e-7)
    assert c.potential_energy(d, th, E2) == pytest.approx(0.018158126, rel=1e-7)


# --------------------------------------------------------------------------------------------
# exactness bound and behaviour beyond it
# --------------------------------------------------------------------------------------------


def test_max_contact_angle_and_within_base_agree():
    d = np.array([0.0, 0.5, 8.0, 15.0, 19.9]) * MM
    bound = c.max_contact_angle(d, A)
    np.testing.assert_allclose(np.tan(bound[1:]), (A - d[1:]) / np.sqrt(A**2 - (A - d[1:]) ** 2))
    assert bound[0] == pytest.approx(math.pi / 2)
    assert bound[2] == pytest.approx(math.atan(12 / 16))  # 3-4-5 triangle at d = 8 mm
    assert np.all(c.contact_within_base(d, bound * (1 - 1e-12), A))
    assert not np.any(c.contact_within_base(d[1:], bound[1:] * (1 + 1e-9), A))
    assert np.all(c.contact_within_base(d, -bound * (1 - 1e-12), A))  # symmetric in theta_p
    assert c.contact_within_base(0.0, 1.5, A)  # d = 0: no contact circle at all


@pytest.mark.parametrize("d_mm", [0.5, 2.0, 8.0, 15.0, 19.9])
def test_closed_forms_exact_up_to_the_bound(d_mm):
    # The closed forms are exact inside the bound, including just below it and at it, where
    # 1/L becomes singular at one boundary point.  Measured max rel. error 6e-11 (at the
    # bound, from the tanh-sinh tail); tolerance 1e-9.
    d = d_mm * MM
    bound = c.max_contact_angle(d, A)
    theta = bound * np.array([0.5, 0.9, 0.999, 1 - 1e-6, 1.0])
    assert np.all(c.contact_within_base(d, theta[:-1], A))  # theta[-1]: rounding decides
    assert _rel(c.stiffness_numeric(d, theta, E2, A), c.stiffness(d, E2)) <= 1e-9
    assert _rel(c.normal_force_numeric(d, theta, E2, A), c.normal_force(d, theta, E2)) <= 1e-9
    P = c.potential_energy_numeric(d, theta, E2, A)
    assert _rel(P, c.potential_energy(d, theta, E2)) <= 1e-9


def test_beyond_bound_closed_forms_over_predict():
    # Documented behaviour: numeric integrals truncate (springs with z_P >= 0 only), so they
    # are continuous at the bound and strictly below the closed forms beyond it.
    d = 8 * MM
    bound = c.max_contact_angle(d, A)
    theta = bound + np.array([1e-6, 1e-3, 0.05, 0.2, 0.5])
    for numeric, closed in (
        (c.stiffness_numeric(d, theta, E2, A), c.stiffness(d, E2)),
        (c.normal_force_numeric(d, theta, E2, A), c.normal_force(d, theta, E2)),
        (c.potential_energy_numeric(d, theta, E2, A), c.potential_energy(d, theta, E2)),
    ):
        ratio = numeric / closed
        assert np.all(ratio < 1)
        assert np.all(np.diff(ratio) < 0)  # the shortfall grows with the tilt
        assert ratio[0] > 1 - 1e-5  # continuous at the bound
    # the worked example of the module docstring: closed-form K 20 % above the integral
    assert c.stiffness(d, E2) / c.stiffness_numeric(d, 42.6 * DEG, E2, A) == pytest.approx(
        1.2013, abs=1e-3
    )


@pytest.mark.parametrize(
    "d_mm, theta_deg", [(8.0, 36.9), (8.0, 65.0), (2.0, 85.0), (15.0, 14.48), (19.99, 5.0)]
)
def test_truncated_integrals_match_independent_reference(d_mm, theta_deg):
    # Beyond the bound the result cannot be checked against a closed form, so compare with
    # the semi-analytic Cartesian reference.  Measured rel. difference <= 3e-11 (K just past
    # the bound, where 1/L is singular at the corner), ~1e-14 otherwise; tolerance 1e-9
    # (the reference's requested accuracy is 1e-12).
    d, th = d_mm * MM, theta_deg * DEG
    assert not c.contact_within_base(d, th, A)
    ref = {q: _semi_analytic_reference(q, d, th) for q in "KFP"}
    assert _rel(c.stiffness_numeric(d, th, 1.0, A), ref["K"]) <= 1e-9
    assert _rel(c.normal_force_numeric(d, th, 1.0, A), ref["F"]) <= 1e-9
    assert _rel(c.potential_energy_numeric(d, th, 1.0, A), ref["P"]) <= 1e-9


@settings(max_examples=40, deadline=None)
@given(
    a=st.floats(5e-3, 50e-3),
    d_frac=st.floats(1e-6, 0.95),
    angle_frac=st.floats(-1.0, 1.0),
    E=st.floats(1e4, 1e8),
)
def test_exact_inside_bound_property(a, d_frac, angle_frac, E):
    # Any geometry inside the bound, either sign of theta_p.  Worst measured 6.4e-11
    # (3000 random draws); tolerance 1e-9.
    d = d_frac * a
    theta = angle_frac * c.max_contact_angle(d, a)
    assert _rel(c.stiffness_numeric(d, theta, E, a), c.stiffness(d, E)) <= 1e-9
    assert _rel(c.normal_force_numeric(d, theta, E, a), c.normal_force(d, theta, E)) <= 1e-9
    P = c.potential_energy_numeric(d, theta, E, a)
    assert _rel(P, c.potential_energy(d, theta, E)) <= 1e-9


# --------------------------------------------------------------------------------------------
# chapter 3: material nonlinearity
# --------------------------------------------------------------------------------------------


def test_stress_fit_units():
    # Eq 3.3 is in % and kPa: sigma(50 %) = 116.2 kPa vs the linear fit 0.232 MPa x 0.5.
    assert c.nonlinear_stress(0.5) == pytest.approx(0.232e6 * 0.5, rel=5e-3)
    assert c.nonlinear_stress(0.0) == 0.0


def test_modulus_is_eq_3_4_and_derivative_of_stress():
    # Recover the quartic's coefficients in kPa per %^i (factor 1e5: kPa/% -> Pa per unit
    # strain) and compare with Eq 3.4, printed to 4 significant digits -> rel. 5e-4.  (Values
    # are compared through the coefficients: the alternating polynomial amplifies the
    # printed rounding to 0.2 % at 60 % strain.)
    printed = np.array([1.829, -2.910e-1, 2.633e-2, -7.632e-4, 7.740e-6])
    eps = np.linspace(0, 1, 11)
    coeffs = np.polynomial.polynomial.polyfit(100 * eps, c.nonlinear_modulus(eps) / 1e5, 4)
    np.testing.assert_allclose(coeffs, printed, rtol=5e-4)
    # central FD of the stress (quintic: truncation h^2 sigma'''/6 ~ 1e-9 rel at h = 1e-5)
    h = 1e-5
    eps = np.linspace(0.01, 0.99, 9)
    fd = (c.nonlinear_stress(eps + h) - c.nonlinear_stress(eps - h)) / (2 * h)
    np.testing.assert_allclose(c.nonlinear_modulus(eps), fd, rtol=1e-7)


@pytest.mark.parametrize("form", c.NONLINEAR_FORMS)
def test_nonlinear_force_axisymmetric_reference(form):
    # theta_p = 0: compare with a 1-D integral over r.  Measured rel. error 6e-15; tol 1e-10.
    law = {"secant": _stress_pa, "printed": lambda e: _tangent_pa(e) * e}[form]
    for d in np.array([0.5, 3.0, 7.0, 10.0]) * MM:
        ref = _axisymmetric_reference(law, d)
        assert _rel(c.nonlinear_normal_force(d, 0.0, A, form), ref) <= 1e-10


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
@pytest.mark.parametrize("form", c.NONLINEAR_FORMS)
def test_nonlinear_force_tilted_reference(form):
    # tilted, inside and beyond the bound: Cartesian quad reference, measured 2e-12
    law = {
        "secant": lambda pq, L: _stress_pa(pq / L),
        "printed": lambda pq, L: _tangent_pa(pq / L) * pq / L,
    }[form]
    for d_mm, deg in ((6.0, 25.0), (8.0, 50.0)):
        ref = _cartesian_reference(law, d_mm * MM, deg * DEG)
        assert _rel(c.nonlinear_normal_force(d_mm * MM, deg * DEG, A, form), ref) <= 1e-9


@pytest.mark.parametrize("form, factor", [("secant", 1.0), ("printed", 2.0)])
def test_nonlinear_small_displacement_limit(form, factor):
    # For small d the spring strains are small: sigma ~ E0 eps (1 + kappa eps) with
    # E0 = 0.1829 MPa and kappa = 100 * (-0.1455) / 1.829; E(eps) eps doubles kappa.  Averaging
    # eps^2 over the contact gives F / (pi E0 d^2) = 1 + factor * kappa * 2 d / (3 a) + O(d^2).
    # At d = 1 um the O(d^2) rest is ~1e-7 (measured 6e-8 secant, 1.7e-7 printed); tolerance
    # 1e-6 on a 2.65e-4 (5.3e-4) first-order term.
    d = 1e-6
    E0, kappa = 0.1829e6, 100 * -0.1455 / 1.829
    ratio = c.nonlinear_normal_force(d, 0.0, A, form) / (math.pi * E0 * d * d)
    assert ratio - 1 == pytest.approx(factor * kappa * 2 * d / (3 * A), abs=1e-6)


def test_printed_force_crosses_linear_once():
    # Fig 3.3 (theta_p = 0, E = 0.232 MPa, a = 20 mm): the literal Eq 3.5 starts below Eq 2.11
    # (E(0) = 0.183 MPa < 0.232 MPa) and ends above it (E rises to 0.61 MPa at 50 %).
    d = np.linspace(0.05, 9.95, 100) * MM
    diff = c.nonlinear_normal_force(d, 0.0, A, "printed") - c.normal_force(d, 0.0, c.E_CH3)
    assert np.count_nonzero(np.diff(np.sign(diff))) == 1

    def gap(x):
        return c.nonlinear_normal_force(x, 0.0, A, "printed") - c.normal_force(x, 0.0, c.E_CH3)

    i = int(np.flatnonzero(np.diff(np.sign(diff)))[0])
    root = optimize.brentq(gap, d[i], d[i + 1], xtol=1e-12)
    assert root == pytest.approx(7.6344 * MM, abs=1e-4 * MM)  # measured 7.634419 mm
    assert c.normal_force(root, 0.0, c.E_CH3) == pytest.approx(42.48, abs=0.01)
    # the secant (default) form stays below the linear one on the whole range
    secant = c.nonlinear_normal_force(d, 0.0, A)
    assert np.all(secant < c.normal_force(d, 0.0, c.E_CH3))


def test_nonlinear_default_form_is_secant():
    d = 5 * MM
    assert c.nonlinear_normal_force(d, 0.1, A) == c.nonlinear_normal_force(d, 0.1, A, "secant")
    assert c.nonlinear_normal_force(d, 0.1, A) != c.nonlinear_normal_force(d, 0.1, A, "printed")


# --------------------------------------------------------------------------------------------
# comparison models
# --------------------------------------------------------------------------------------------


def test_hertz_force():
    d = np.array([1.0, 4.0]) * MM
    F = c.hertz_force(d, A, c.E_CH3)
    assert F[1] / F[0] == pytest.approx(8.0, rel=1e-12)  # d^1.5
    expected = 4 * math.sqrt(A) / 3 * c.E_CH3 / 0.75 * (4 * MM) ** 1.5
    assert F[1] == pytest.approx(expected, rel=1e-12)
    assert c.hertz_force(4 * MM, A, c.E_CH3, poisson=0.0) == pytest.approx(0.75 * F[1])
    assert c.hertz_force(0.0, A, c.E_CH3) == 0.0


def test_power_law_force():
    assert c.power_law_force(2 * MM, 5e4, 1.75) / c.power_law_force(MM, 5e4, 1.75) == (
        pytest.approx(2**1.75, rel=1e-12)
    )
    assert c.power_law_force(3 * MM, 2.0, 2.3) == pytest.approx(2.0 * (3 * MM) ** 2.3)


# --------------------------------------------------------------------------------------------
# Eq 5.4: compression + bending
# --------------------------------------------------------------------------------------------


def test_bending_energy_reduces_to_eq_2_14_and_is_mirror_symmetric():
    d_n, th = np.array([1.0, 4.0, 8.0]) * MM, np.array([-20.0, 5.0, 30.0]) * DEG
    np.testing.assert_allclose(
        c.bending_energy(d_n, 0.0, th, E2), c.potential_energy(d_n, th, E2), rtol=1e-14
    )
    for sign in (-1.0, 1.0):
        P = c.bending_energy(d_n, 1.5 * MM, th, E2, sign)
        np.testing.assert_allclose(P, c.bending_energy(d_n, -1.5 * MM, -th, E2, sign), rtol=1e-14)
    # the sign only flips the cross term: P(+1) - P(-1) = 2 pi E d_n^2 d_t tan
    diff = c.bending_energy(d_n, MM, th, E2, 1.0) - c.bending_energy(d_n, MM, th, E2)
    np.testing.assert_allclose(diff, 2 * math.pi * E2 * d_n**2 * MM * np.tan(th), rtol=1e-12)
    # Eq 5.5 with (-1)^i as an array of signs
    per_finger = c.bending_energy(4 * MM, MM, 0.2, E2, np.array([-1.0, 1.0]))
    assert per_finger.shape == (2,)
    assert per_finger[0] == c.bending_energy(4 * MM, MM, 0.2, E2, -1.0)


def test_bending_gradient_matches_central_differences():
    # Points with s * d_t * theta_p >= 0 so no component cancels to ~0 (relative test
    # meaningful).  Steps 1e-9 m / 1e-7 rad: truncation ~1e-12, round-off ~1e-9 rel
    # (measured 2.2e-9); tolerance 1e-6 is the acceptance target.
    rng = np.random.default_rng(7)
    n = 40
    d_n = rng.uniform(0.5, 8.0, n) * MM
    sign = rng.choice([-1.0, 1.0], n)
    theta = rng.uniform(-40, 40, n) * DEG
    d_t = sign * np.sign(theta) * rng.uniform(0.1, 3.0, n) * MM
    E = rng.uniform(1e5, 1e6, n)
    g = c.bending_energy_gradient(d_n, d_t, theta, E, sign)
    assert g.shape == (n, 3)
    steps = (1e-9, 1e-9, 1e-7)
    args = [d_n, d_t, theta]
    for k, h in enumerate(steps):
        plus, minus = list(args), list(args)
        plus[k], minus[k] = args[k] + h, args[k] - h
        fd = (c.bending_energy(*plus, E, sign) - c.bending_energy(*minus, E, sign)) / (2 * h)
        np.testing.assert_allclose(g[:, k], fd, rtol=1e-6)


def test_bending_gradient_shapes():
    assert c.bending_energy_gradient(4 * MM, 0.0, 0.0, E2).shape == (3,)
    g = c.bending_energy_gradient(np.full((2, 1), 4 * MM), np.zeros(5), 0.1, E2)
    assert g.shape == (2, 5, 3)
    # theta_p = 0, d_t = 0: only dP/dd_n = pi E d_n^2 = F (Eq D.2) survives
    np.testing.assert_allclose(
        c.bending_energy_gradient(4 * MM, 0.0, 0.0, E2),
        [c.normal_force(4 * MM, 0.0, E2), 0.0, 0.0],
    )


# --------------------------------------------------------------------------------------------
# validation and vectorisation
# --------------------------------------------------------------------------------------------

BAD_INPUTS = [
    (c.stiffness, dict(d=-1e-3, E=E2), "d"),
    (c.stiffness, dict(d=1e-3, E=0.0), "E"),
    (c.stiffness, dict(d=np.nan, E=E2), "d"),
    (c.normal_force, dict(d=1e-3, theta_p=math.pi / 2, E=E2), "theta_p"),
    (c.normal_force, dict(d=1e-3, theta_p=[0.0, -2.0], E=E2), "theta_p"),
    (c.potential_energy, dict(d=1e-3, theta_p=0.0, E=np.inf), "E"),
    (c.stiffness_numeric, dict(d=0.02, theta_p=0.0, E=E2, a=0.02), "d"),
    (c.normal_force_numeric, dict(d=[1e-3, 0.03], theta_p=0.0, E=E2, a=0.02), "d"),
    (c.potential_energy_numeric, dict(d=1e-3, theta_p=0.0, E=E2, a=0.0), "a"),
    (c.potential_energy_numeric, dict(d=1e-3, theta_p=0.0, E=-1.0, a=A), "E"),
    (c.normal_force_numeric, dict(d=1e-3, theta_p=float("nan"), E=E2, a=A), "theta_p"),
    (c.contact_within_base, dict(d=1e-3, theta_p=0.0, a=-A), "a"),
    (c.max_contact_angle, dict(d=-1e-3, a=A), "d"),
    (c.nonlinear_stress, dict(strain=-0.1), "strain"),
    (c.nonlinear_modulus, dict(strain=1.5), "strain"),
    (c.nonlinear_normal_force, dict(d=1e-3, theta_p=0.0, a=A, form="tangent"), "form"),
    (c.nonlinear_normal_force, dict(d=0.025, theta_p=0.0, a=A), "d"),
    (c.hertz_force, dict(d=1e-3, R=0.0, E=E2), "R"),
    (c.hertz_force, dict(d=1e-3, R=A, E=E2, poisson=0.6), "poisson"),
    (c.power_law_force, dict(d=1e-3, c_d=1.0, zeta=0.0), "zeta"),
    (c.power_law_force, dict(d=1e-3, c_d=-1.0, zeta=2.0), "c_d"),
    (c.bending_energy, dict(d_n=-1e-3, d_t=0.0, theta_p=0.0, E=E2), "d_n"),
    (c.bending_energy, dict(d_n=1e-3, d_t=np.inf, theta_p=0.0, E=E2), "d_t"),
    (c.bending_energy, dict(d_n=1e-3, d_t=0.0, theta_p=0.0, E=E2, cross_sign=0.5), "cross_sign"),
    (c.bending_energy_gradient, dict(d_n=1e-3, d_t=0.0, theta_p=1.6, E=E2), "theta_p"),
    (c.stiffness, dict(d="abc", E=E2), "d"),
]


@pytest.mark.parametrize(
    "func, kwargs, name", BAD_INPUTS, ids=[f"{f.__name__}-{n}" for f, _, n in BAD_INPUTS]
)
def test_bad_input_names_the_argument(func, kwargs, name):
    with pytest.raises(ValueError, match=rf"^{name} must be"):
        func(**kwargs)


def test_d_range_message_shows_values():
    with pytest.raises(ValueError, match=r"d must be >= 0 and < a \(got d=0.03, a=0.02\)"):
        c.normal_force_numeric([0.001, 0.03], 0.0, E2, 0.02)


def test_zero_displacement_is_valid():
    assert c.normal_force(0.0, 0.3, E2) == 0.0
    for f in (c.stiffness_numeric, c.normal_force_numeric, c.potential_energy_numeric):
        assert f(0.0, 0.3, E2, A) == 0.0
    assert c.nonlinear_normal_force(0.0, 0.3, A) == 0.0


def test_scalars_give_numpy_scalars():
    for value in (
        c.stiffness(1e-3, E2),
        c.normal_force(1e-3, 0.1, E2),
        c.stiffness_numeric(1e-3, 0.1, E2, A),
        c.normal_force_numeric(np.float64(1e-3), np.array(0.1), E2, A),
        c.nonlinear_normal_force(1e-3, 0.1, A),
        c.nonlinear_stress(0.2),
        c.hertz_force(1e-3, A, E2),
        c.bending_energy(1e-3, 0.0, 0.1, E2),
        c.max_contact_angle(1e-3, A),
    ):
        assert np.ndim(value) == 0 and isinstance(value, np.floating)
    assert isinstance(c.contact_within_base(1e-3, 0.1, A), np.bool_)


def test_broadcasting_shapes():
    d = np.linspace(1, 8, 3)[:, None] * MM
    th = np.linspace(-20, 20, 4) * DEG
    E = np.array([[[1e5]], [[2e5]]])  # (2, 1, 1)
    assert c.normal_force(d, th, E2).shape == (3, 4)
    assert c.normal_force_numeric(d, th, E2, A).shape == (3, 4)
    F = c.normal_force_numeric(d, th, E, A)
    assert F.shape == (2, 3, 4)
    np.testing.assert_allclose(F[1], 2 * F[0], rtol=1e-15)
    radii = np.array([20.0, 30.0]) * MM
    assert c.stiffness_numeric(d, 0.0, E2, radii).shape == (3, 2)
    assert c.contact_within_base(d, th, A).dtype == bool
    assert c.nonlinear_normal_force(d, th, A, "printed").shape == (3, 4)
    assert c.max_contact_angle(d, radii).shape == (3, 2)
    # element-wise evaluation equals the broadcast result (chunking does not mix sets)
    big_d = np.linspace(0.5, 19.0, 200) * MM
    big_th = np.linspace(-80, 80, 200) * DEG
    batch = c.potential_energy_numeric(big_d, big_th, E2, A)
    pairs = zip(big_d[::37], big_th[::37], strict=True)
    single = [c.potential_energy_numeric(x, t, E2, A) for x, t in pairs]
    np.testing.assert_allclose(batch[::37], single, rtol=1e-14)


def test_grid_is_fast():
    # a 30 x 30 grid must stay well under a few seconds (measured ~0.3 s per function)
    import time

    d = np.linspace(0.5, 8, 30)[:, None] * MM
    th = np.linspace(0, 30, 30) * DEG
    start = time.perf_counter()
    c.normal_force_numeric(d, th, E2, A)
    assert time.perf_counter() - start < 2.0
