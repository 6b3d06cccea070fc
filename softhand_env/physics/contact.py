r"""Soft-fingertip contact models (chapters 2, 3 and Eq 5.4 of the dissertation).

A hemispherical fingertip of radius ``a`` on its flat base is a bed of vertical virtual linear
springs (Fig 2.1) pressed by a rigid planar object tilted by ``theta_p`` with the maximum
displacement ``d``. Units are SI throughout: ``d`` and ``a`` in m, angles in rad, ``E`` in Pa,
forces in N, energies in J, stiffness in N/m.

* Closed forms (chapter 2): :func:`stiffness`, :func:`normal_force`, :func:`potential_energy`;
  exact while the contact circle stays above the fingertip base (:func:`beyond_base`,
  :func:`contact_within_base`, :func:`max_contact_angle`).
* Numerical integrals over the (truncated) contact region: :func:`stiffness_numeric`,
  :func:`normal_force_numeric`, :func:`potential_energy_numeric`.
* Material nonlinearity (chapter 3): :func:`nonlinear_stress`, :func:`nonlinear_modulus`,
  :func:`nonlinear_normal_force`; comparison models :func:`hertz_force`, :func:`power_law_force`.
* Compression + bending energy of one fingertip (Eq 5.4): :func:`bending_energy`,
  :func:`bending_energy_gradient`.

Derivations, the exactness bound, units of Eqs 3.3-3.5 and the cross-term sign:
``docs/contact.md``. Every public function raises :class:`ValueError` naming the offending
argument for out-of-range input; scalar arguments give NumPy scalars, arrays broadcast.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.polynomial import polynomial as _poly
from numpy.typing import ArrayLike

__all__ = [
    "E_CH2",
    "E_CH3",
    "FINGERTIP_RADIUS",
    "STRESS_FIT_KPA_PERCENT",
    "NONLINEAR_FORMS",
    "stiffness",
    "normal_force",
    "potential_energy",
    "stiffness_numeric",
    "normal_force_numeric",
    "potential_energy_numeric",
    "contact_within_base",
    "max_contact_angle",
    "nonlinear_stress",
    "nonlinear_modulus",
    "nonlinear_normal_force",
    "hertz_force",
    "power_law_force",
    "bending_energy",
    "bending_energy_gradient",
]

#: Young's modulus of the linear fit of chapter 2 (Fig 2.4), Pa.
E_CH2 = 0.2032e6
#: Young's modulus of the linear fit of chapter 3 (Fig 3.2-(b), used in Fig 3.3), Pa.
E_CH3 = 0.232e6
#: Fingertip radius of the experiments (40 mm diameter), m.
FINGERTIP_RADIUS = 0.020
#: Coefficients a_1..a_5 of Eq 3.3, in kPa / %^i (strain in percent, stress in kPa).
STRESS_FIT_KPA_PERCENT = (1.829, -1.455e-1, 8.778e-3, -1.908e-4, 1.548e-6)
#: Accepted values of ``form`` in :func:`nonlinear_normal_force` (first one is the default).
NONLINEAR_FORMS = ("secant", "printed")

# sigma_Pa(eps) = sum_i c_i eps^i with eps a fraction: c_i = 1e3 (kPa->Pa) * 100^i (%->1) * a_i
_STRESS_COEFFS_PA = np.array(
    [0.0] + [1e3 * 100.0**i * c for i, c in enumerate(STRESS_FIT_KPA_PERCENT, start=1)]
)
_MODULUS_COEFFS_PA = _poly.polyder(_STRESS_COEFFS_PA)

# --------------------------------------------------------------------------------------------
# input handling
# --------------------------------------------------------------------------------------------


def _real(name: str, value: ArrayLike) -> np.ndarray:
    """``value`` as a finite float array, or ValueError naming ``name``."""
    if np.iscomplexobj(value):
        raise ValueError(f"{name} must be real (got {value!r})")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number or array (got {value!r})") from None
    _require(name, np.isfinite(arr), "finite", arr)
    return arr


def _require(name: str, ok: np.ndarray, rule: str, *shown: np.ndarray, labels=()) -> None:
    """Raise ``ValueError("<name> must be <rule> (got ...)")`` unless ``ok`` holds everywhere."""
    if np.all(ok):
        return
    ok = np.asarray(ok)
    first = np.flatnonzero(~ok)[0]
    values = [np.broadcast_to(v, ok.shape).flat[first] for v in shown]
    if labels:
        got = ", ".join(f"{lab}={v:g}" for lab, v in zip(labels, values, strict=True))
    else:
        got = ", ".join(f"{v:g}" for v in values)
    raise ValueError(f"{name} must be {rule} (got {got})")


def _positive(name: str, value: ArrayLike) -> np.ndarray:
    arr = _real(name, value)
    _require(name, arr > 0, "> 0", arr)
    return arr


def _angle(theta_p: ArrayLike) -> np.ndarray:
    theta = _real("theta_p", theta_p)
    _require("theta_p", np.abs(theta) < np.pi / 2, "in (-pi/2, pi/2) rad", theta)
    return theta


def _depth(d: ArrayLike, a: np.ndarray | None = None) -> np.ndarray:
    """Validated displacement ``d`` (>= 0, and < ``a`` when the radius is known)."""
    d = _real("d", d)
    if a is None:
        _require("d", d >= 0, ">= 0", d)
    else:
        _require("d", (d >= 0) & (d < a), ">= 0 and < a", d, a, labels=("d", "a"))
    return d


def _geometry(d: ArrayLike, theta_p: ArrayLike, a: ArrayLike):
    """Validated ``(d, theta_p, a)`` of the fingertip-geometry functions."""
    a = _positive("a", a)
    return _depth(d, a), _angle(theta_p), a


def _out(x: np.ndarray):
    """NumPy scalar for 0-d results, the array otherwise."""
    x = np.asarray(x)
    return x[()] if x.ndim == 0 else x


# --------------------------------------------------------------------------------------------
# chapter 2: closed forms
# --------------------------------------------------------------------------------------------


def stiffness(d: ArrayLike, E: ArrayLike):
    """Fingertip stiffness ``K = 2 pi E d`` (Eq 2.7), exact inside the bound.

    Parameters
    ----------
    d : array_like
        Maximum displacement of the fingertip, m, ``>= 0``.
    E : array_like
        Young's modulus, Pa, ``> 0``.

    Returns
    -------
    float or ndarray
        ``K`` in N/m, shape ``broadcast(d, E)``.  Independent of ``theta_p`` inside the bound
        (:func:`contact_within_base`); over-predicts beyond it.
    """
    E = _positive("E", E)
    return _out(2 * np.pi * E * _depth(d))


def normal_force(d: ArrayLike, theta_p: ArrayLike, E: ArrayLike):
    """Elastic force ``F = pi E d^2 / cos(theta_p)`` (Eq 2.11), exact inside the bound.

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``>= 0``.
    theta_p : array_like
        Object orientation angle, rad, ``|theta_p| < pi/2``.
    E : array_like
        Young's modulus, Pa, ``> 0``.

    Returns
    -------
    float or ndarray
        ``F`` in N (the sum of the vertical spring forces, Eq 2.8), shape
        ``broadcast(d, theta_p, E)``.  Local minimum at ``theta_p = 0`` for fixed ``d``.
        Accepted for any ``|theta_p| < pi/2`` but over-predicts beyond
        :func:`max_contact_angle`.
    """
    E = _positive("E", E)
    d, theta = _depth(d), _angle(theta_p)
    return _out(np.pi * E * d**2 / np.cos(theta))


def potential_energy(d: ArrayLike, theta_p: ArrayLike, E: ArrayLike):
    """Elastic potential energy ``P = pi E d^3 / (3 cos^2 theta_p)`` (Eq 2.14).

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``>= 0``.
    theta_p : array_like
        Object orientation angle, rad, ``|theta_p| < pi/2``.
    E : array_like
        Young's modulus, Pa, ``> 0``.

    Returns
    -------
    float or ndarray
        ``P`` in J, shape ``broadcast(d, theta_p, E)``.  Exact inside the bound, over-predicts
        beyond it.  Note (Appendix D): ``dP/dd = F / cos(theta_p)``, so ``F = dP/dd`` only at
        ``theta_p = 0``; in general ``F = dP/d(dz_eq)`` with ``d = dz_eq cos(theta_p)``.
    """
    E = _positive("E", E)
    d, theta = _depth(d), _angle(theta_p)
    return _out(np.pi * E * d**3 / (3 * np.cos(theta) ** 2))


# --------------------------------------------------------------------------------------------
# exactness bound
# --------------------------------------------------------------------------------------------


def _contact_radius(d: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``a_c = sqrt(a^2 - (a-d)^2)``, written without cancellation for small ``d``."""
    return np.sqrt(d * (2 * a - d))


def beyond_base(d, theta_p, a, limit=1.0):
    """True where the contact circle reaches past the fingertip base by more than ``limit``.

    The single past-the-base test (the kernels compile this source): ``|tan theta_p| a_c /
    (a - d) > limit`` in the cancellation-free form ``a_c |sin theta_p| > limit (a - d) cos
    theta_p`` with ``a_c = sqrt(d (2a - d))`` (no ``a^2 - (a - d)^2``, no tangent). ``limit = 1``
    is the base itself (the closed forms are exact below it); above 1 the closed-form energy
    over-predicts: by 0.3 % (force 1 %) at 1.03, 1 % (force 2 %) at 1.05 (d = 5-8.5 mm,
    against :func:`potential_energy_numeric`); ``limit = inf`` never fires.

    Parameters
    ----------
    d : float or ndarray
        Normal deformation (m), ``0 <= d < a``.
    theta_p : float or ndarray
        Contact angle (rad), ``|theta_p| < pi/2``.
    a : float or ndarray
        Fingertip radius (m).
    limit : float
        Allowed reach (dimensionless, >= 1).

    Returns
    -------
    bool or ndarray of bool
        Shape ``broadcast(d, theta_p, a)``.
    """
    return np.sqrt(d * (2.0 * a - d)) * np.abs(np.sin(theta_p)) > limit * (
        (a - d) * np.cos(theta_p)
    )


def contact_within_base(d: ArrayLike, theta_p: ArrayLike, a: ArrayLike):
    """Whether the closed forms are exact: ``|tan(theta_p)| <= (a - d) / a_c``.

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``0 <= d < a``.
    theta_p : array_like
        Object orientation angle, rad, ``|theta_p| < pi/2``.
    a : array_like
        Fingertip radius, m, ``> 0``.

    Returns
    -------
    bool or ndarray of bool
        Shape ``broadcast(d, theta_p, a)``.  True while the whole contact circle lies on or
        above the base plane ``z = 0`` (always true for ``d = 0``).
    """
    d, theta, a = _geometry(d, theta_p, a)
    return _out(~beyond_base(d, theta, a))


def max_contact_angle(d: ArrayLike, a: ArrayLike):
    """Largest ``|theta_p|`` for which the closed forms are exact, ``arctan((a - d) / a_c)``.

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``0 <= d < a``.
    a : array_like
        Fingertip radius, m, ``> 0``.

    Returns
    -------
    float or ndarray
        Angle in rad in ``(0, pi/2]`` (``pi/2`` at ``d = 0``), shape ``broadcast(d, a)``.
        E.g. ``a = 20 mm``: 77.2 deg at ``d = 0.5 mm``, 36.9 deg at 8 mm, 14.5 deg at 15 mm.
    """
    a = _positive("a", a)
    d = _depth(d, a)
    return _out(np.arctan2(a - d, _contact_radius(d, a)))


# --------------------------------------------------------------------------------------------
# chapter 2: numerical integration over the (truncated) contact ellipse
# --------------------------------------------------------------------------------------------
#
# In the coordinates of Appendix C, (r, phi) span the contact disc (centre C, radius a_c) of
# the object plane.  With h = a - d, the plane height above (x, y) is
#     z_P = h cos(theta) - r cos(phi) sin(theta),
# and the natural spring length satisfies L^2 = z_P^2 + (a_c^2 - r^2) because |P|^2 =
# h^2 + r^2.  Hence L and PQ = L - z_P = (a_c^2 - r^2) / (L + z_P) are evaluated without
# cancellation, even at the singular corner.  The integrand is even in phi (y -> -y), so phi
# runs over [0, pi] and the result is doubled; F(theta) = F(-theta) (x -> -x), so |theta| is
# used.  Truncation (springs with z_P >= 0 only) cuts the disc by the chord
# r cos(phi) <= h / tan(theta), i.e. phi in [0, phi_c] has r_max(phi) = a_c cos(phi_c)/cos(phi)
# and phi in [phi_c, pi] has r_max = a_c, with cos(phi_c) = h / (a_c tan(theta)); inside the
# bound phi_c = 0.  Each block is a tanh-sinh product rule: it converges double-exponentially
# for the analytic integrand and also for the 1/sqrt endpoint singularity of 1/L at the corner
# (r, phi) = (a_c, phi_c) that exists at and beyond the bound.

_TANH_SINH_HALF_NODES = 40  # measured: <= 6e-11 rel. error up to the bound, ~4e-15 inside
_TANH_SINH_T_MAX = 3.6  # tail ~ exp(-pi sinh 3.6 / 2) ~ 3e-13 even for 1/sqrt singularities
_CHUNK_NODES = 1 << 19  # nodes evaluated at once (memory ~ a few MB per temporary)


def _tanh_sinh_rule(half_nodes: int, t_max: float):
    """Nodes ``x``, complements ``1 - x`` (accurate near 1) and weights on ``[0, 1]``."""
    t = np.linspace(-t_max, t_max, 2 * half_nodes + 1)
    s = np.pi * np.sinh(t)
    x, xc = 1 / (1 + np.exp(-s)), 1 / (1 + np.exp(s))
    return x, xc, (t[1] - t[0]) * np.pi * np.cosh(t) * x * xc


_X, _XC, _W = _tanh_sinh_rule(_TANH_SINH_HALF_NODES, _TANH_SINH_T_MAX)

#: density(pq, L) -> integrand per unit base area; pq = compression PQ, L = natural length.
Density = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _sum_rays(density: Density, rays: dict, a_c: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
    """``sum_phi w_phi int_0^r_max density r dr`` for rays of shape (sets, n_phi)."""
    r_max = rays["r_max"][..., None]
    r = r_max * _X
    span = (rays["gap"][..., None] + r_max * _XC) * (a_c[:, None, None] + r)  # a_c^2 - r^2
    slope = (rays["r_max"] * rays["cos_phi"] * sin_t[:, None])[..., None]
    z_p = rays["z_end"][..., None] + slope * _XC
    length = np.sqrt(z_p * z_p + span)
    pq = span / (length + z_p)
    inner = np.sum(r_max * _W * r * density(pq, length), axis=-1)
    return np.sum(rays["w_phi"] * inner, axis=-1)


def _uncut_rays(phi_c, a_c, z_c, sin_t) -> dict:
    """Rays over ``phi in [phi_c, pi]``: the full contact disc radius ``a_c``."""
    span = (np.pi - phi_c)[:, None]
    cos_phi = np.cos(phi_c[:, None] + span * _X)
    z_end = np.maximum(z_c[:, None] - a_c[:, None] * cos_phi * sin_t[:, None], 0.0)
    r_max = np.broadcast_to(a_c[:, None], cos_phi.shape)
    return dict(w_phi=span * _W, cos_phi=cos_phi, r_max=r_max, gap=0.0 * cos_phi, z_end=z_end)


def _cut_rays(phi_c, a_c) -> dict:
    """Rays over ``phi in [0, phi_c]``, ending on the chord ``z_P = 0`` (beyond the bound)."""
    phi = phi_c[:, None] * _XC
    cos_phi = np.cos(phi)
    # a_c - r_max = a_c (cos phi - cos phi_c) / cos phi, written as a sine product
    gap = 2 * a_c[:, None] * np.sin(0.5 * (phi_c[:, None] + phi))
    gap *= np.sin(0.5 * phi_c[:, None] * _X) / cos_phi
    r_max = a_c[:, None] * np.cos(phi_c)[:, None] / cos_phi
    return dict(w_phi=phi_c[:, None] * _W, cos_phi=cos_phi, r_max=r_max, gap=gap, z_end=0 * gap)


def _integrate_sets(density: Density, d, theta, a) -> np.ndarray:
    """``int int density dx dy`` over the truncated contact region; 1-D arrays of sets."""
    a_c = _contact_radius(d, a)
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    z_c = (a - d) * cos_t  # height of the contact-disc centre C
    beyond = beyond_base(d, theta, a)
    phi_c = np.zeros_like(d)
    phi_c[beyond] = np.arccos(z_c[beyond] / (a_c[beyond] * sin_t[beyond]))
    total = _sum_rays(density, _uncut_rays(phi_c, a_c, z_c, sin_t), a_c, sin_t)
    if beyond.any():
        cut = _cut_rays(phi_c[beyond], a_c[beyond])
        total[beyond] += _sum_rays(density, cut, a_c[beyond], sin_t[beyond])
    return 2 * cos_t * total


def _contact_integral(density: Density, d, theta_p, a) -> np.ndarray:
    """Vectorised driver: broadcast ``(d, |theta_p|, a)`` and integrate in memory-sized chunks."""
    shape = np.broadcast_shapes(np.shape(d), np.shape(theta_p), np.shape(a))
    d, theta, a = (np.ravel(v) for v in np.broadcast_arrays(d, np.abs(theta_p), a))
    out = np.empty(d.size)
    step = max(1, _CHUNK_NODES // (2 * _X.size**2))
    for start in range(0, d.size, step):
        chunk = slice(start, start + step)
        out[chunk] = _integrate_sets(density, d[chunk], theta[chunk], a[chunk])
    return out.reshape(shape)


def _stiffness_density(pq, length):
    return 1.0 / length  # k / (E dS), Eq 2.2


def _force_density(pq, length):
    return pq / length  # k PQ / (E dS) = strain, Eq 2.8 (QT / cos = PQ)


def _energy_density(pq, length):
    return 0.5 * pq * pq / length  # k PQ^2 / (2 E dS), Eq 2.12


def _numeric(density: Density, d, theta_p, E, a):
    E = _positive("E", E)
    d, theta, a = _geometry(d, theta_p, a)
    return _out(E * _contact_integral(density, d, theta, a))


_NUMERIC_DOC = """{what} by numerical integration of Eq {eq} over the contact ellipse.

    Integrates ``{integrand}`` over the region bounded by ``b1(y), b2(y)`` (Eqs 2.4-2.5) with the
    Appendix C substitution and a tanh-sinh product rule (module docstring).  Inside the bound
    (:func:`contact_within_base`) the result equals the closed form :func:`{closed}` to ~1e-14
    relative (<= 1e-10 at the bound).  Beyond the bound only springs whose contact point lies
    on or above the base (``z_P >= 0``) are integrated: the result is then smaller than the
    closed form.

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``0 <= d < a``.
    theta_p : array_like
        Object orientation angle, rad, ``|theta_p| < pi/2``.
    E : array_like
        Young's modulus, Pa, ``> 0``.
    a : array_like
        Fingertip radius, m, ``> 0``.

    Returns
    -------
    float or ndarray
        {what} in {unit}, shape ``broadcast(d, theta_p, E, a)``.  About 0.3 ms per point.
    """


def stiffness_numeric(d: ArrayLike, theta_p: ArrayLike, E: ArrayLike, a: ArrayLike):
    return _numeric(_stiffness_density, d, theta_p, E, a)


def normal_force_numeric(d: ArrayLike, theta_p: ArrayLike, E: ArrayLike, a: ArrayLike):
    return _numeric(_force_density, d, theta_p, E, a)


def potential_energy_numeric(d: ArrayLike, theta_p: ArrayLike, E: ArrayLike, a: ArrayLike):
    return _numeric(_energy_density, d, theta_p, E, a)


stiffness_numeric.__doc__ = _NUMERIC_DOC.format(
    what="Stiffness K", eq="2.3", integrand="E / L", closed="stiffness", unit="N/m"
)
normal_force_numeric.__doc__ = _NUMERIC_DOC.format(
    what="Elastic force F", eq="2.8", integrand="E PQ / L", closed="normal_force", unit="N"
)
potential_energy_numeric.__doc__ = _NUMERIC_DOC.format(
    what="Potential energy P",
    eq="2.12",
    integrand="E PQ^2 / (2 L)",
    closed="potential_energy",
    unit="J",
)


# --------------------------------------------------------------------------------------------
# chapter 3: material nonlinearity
# --------------------------------------------------------------------------------------------


def _strain(strain: ArrayLike) -> np.ndarray:
    strain = _real("strain", strain)
    _require("strain", (strain >= 0) & (strain <= 1), "in [0, 1] (a fraction)", strain)
    return strain


def nonlinear_stress(strain: ArrayLike):
    """Compressive stress of the quintic fit, Eq 3.3, converted to SI.

    Eq 3.3 is printed with strain in percent and stress in kPa; this function evaluates
    ``sigma_Pa(eps) = 1e3 * sigma_kPa(100 * eps)``.  ``sigma(0.5) = 116.2 kPa``, i.e. the linear
    fit ``0.232 MPa x 0.5`` within 0.2 %.  The fit describes the compression test of §3.2;
    strains beyond ~0.5 extrapolate it (it stays monotonic up to 1).

    Parameters
    ----------
    strain : array_like
        Compressive strain as a fraction, ``0 <= strain <= 1``.

    Returns
    -------
    float or ndarray
        Stress in Pa, same shape as ``strain``.
    """
    return _out(_poly.polyval(_strain(strain), _STRESS_COEFFS_PA))


def nonlinear_modulus(strain: ArrayLike):
    """Tangent Young's modulus ``E(eps) = d sigma / d eps`` of the fit (Eq 3.4), in Pa.

    Eq 3.4 is the derivative of Eq 3.3 in kPa per percent strain; with the strain as a fraction
    the modulus in Pa is ``1e5 * E_3.4(100 * eps)`` (``1e3`` Pa/kPa times ``100`` %/unit
    strain).  ``E(0) = 0.1829 MPa``; minimum 0.0827 MPa at 8.0 %; ``E(0.5) = 0.609 MPa``.

    Parameters
    ----------
    strain : array_like
        Compressive strain as a fraction, ``0 <= strain <= 1``.

    Returns
    -------
    float or ndarray
        Tangent modulus in Pa, same shape as ``strain``.
    """
    return _out(_poly.polyval(_strain(strain), _MODULUS_COEFFS_PA))


def _secant_density(pq, length):
    return _poly.polyval(pq / length, _STRESS_COEFFS_PA)  # sigma(eps) dS


def _printed_density(pq, length):
    strain = pq / length
    return _poly.polyval(strain, _MODULUS_COEFFS_PA) * strain  # E(eps) eps dS, Eq 3.5


_NONLINEAR_DENSITIES = {"secant": _secant_density, "printed": _printed_density}


def nonlinear_normal_force(d: ArrayLike, theta_p: ArrayLike, a: ArrayLike, form: str = "secant"):
    """Elastic force with material nonlinearity (Eq 3.5), by numerical integration.

    Each virtual spring carries the strain ``eps = PQ / L`` of Eq 3.6 and the force
    ``form="secant"`` (default): ``sigma(eps) dS`` -- the stress of the fitted curve, Eq 3.3;
    consistent with the strain energy and with the uniaxial test the fit came from.
    ``form="printed"``: ``E(eps) eps dS`` -- Eq 3.5 literally, the *tangent* modulus (Eq 3.4)
    times the strain, i.e. Eq 2.2 with ``E -> E(eps)``.  Both reduce to Eq 2.8 for a linear
    material.  The region and its truncation beyond the bound are those of
    :func:`normal_force_numeric` (so ``0 <= eps <= 1``).  At ``theta_p = 0, a = 20 mm`` the
    printed force crosses Eq 2.11 with ``E = 0.232 MPa`` once, at ``d = 7.634 mm``; the secant
    force stays below it for ``d <= 10 mm``.

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``0 <= d < a``.
    theta_p : array_like
        Object orientation angle, rad, ``|theta_p| < pi/2``.
    a : array_like
        Fingertip radius, m, ``> 0``.
    form : {"secant", "printed"}
        Spring force law, see above.

    Returns
    -------
    float or ndarray
        Force in N, shape ``broadcast(d, theta_p, a)``.
    """
    if form not in _NONLINEAR_DENSITIES:
        raise ValueError(f"form must be one of {NONLINEAR_FORMS} (got {form!r})")
    d, theta, a = _geometry(d, theta_p, a)
    return _out(_contact_integral(_NONLINEAR_DENSITIES[form], d, theta, a))


# --------------------------------------------------------------------------------------------
# chapter 3: comparison models
# --------------------------------------------------------------------------------------------


def hertz_force(d: ArrayLike, R: ArrayLike, E: ArrayLike, poisson: ArrayLike = 0.5):
    """Hertz contact of an elastic sphere on a rigid plane (Eq 3.1), for comparison only.

    ``F = (4 sqrt(R) / 3) * E / (1 - poisson^2) * d^(3/2)``.  It has no contact angle and no
    boundary (no finite hemisphere); the dissertation shows it does not fit soft fingertips.

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``>= 0``.
    R : array_like
        Sphere radius, m, ``> 0``.
    E : array_like
        Young's modulus, Pa, ``> 0``.
    poisson : array_like, optional
        Poisson's ratio (``sigma`` in the text), ``-1 < poisson <= 0.5``; 0.5 (incompressible)
        by default.

    Returns
    -------
    float or ndarray
        Force in N, shape ``broadcast(d, R, E, poisson)``.
    """
    R, E, nu = _positive("R", R), _positive("E", E), _real("poisson", poisson)
    _require("poisson", (nu > -1) & (nu <= 0.5), "> -1 and <= 0.5", nu)
    return _out(4 * np.sqrt(R) / 3 * E / (1 - nu**2) * _depth(d) ** 1.5)


def power_law_force(d: ArrayLike, c_d: ArrayLike, zeta: ArrayLike):
    """Kao's empirical power law ``F = c_d d^zeta`` (Eq 3.2), for comparison only.

    Kao et al. report ``zeta ~ 1.75`` below and ``~ 2.3`` above 20 % deformation.

    Parameters
    ----------
    d : array_like
        Maximum displacement, m, ``>= 0``.
    c_d : array_like
        Coefficient in N / m^zeta, ``> 0`` (a value in N / mm^zeta is ``1000^zeta`` times
        larger in these units).
    zeta : array_like
        Exponent, ``> 0``.

    Returns
    -------
    float or ndarray
        Force in N, shape ``broadcast(d, c_d, zeta)``.
    """
    c_d, zeta = _positive("c_d", c_d), _positive("zeta", zeta)
    return _out(c_d * _depth(d) ** zeta)


# --------------------------------------------------------------------------------------------
# chapter 5: compression + bending energy of one fingertip
# --------------------------------------------------------------------------------------------


def _bending_args(
    d_n: ArrayLike, d_t: ArrayLike, theta_p: ArrayLike, E: ArrayLike, cross_sign: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validated ``(d_n, d_t, theta_p, E, cross_sign)`` of the bending-energy functions."""
    n = _real("d_n", d_n)
    _require("d_n", n >= 0, ">= 0", n)
    sign = _real("cross_sign", cross_sign)
    _require("cross_sign", np.abs(sign) == 1, "+1 or -1", sign)
    return n, _real("d_t", d_t), _angle(theta_p), _positive("E", E), sign


def bending_energy(
    d_n: ArrayLike,
    d_t: ArrayLike,
    theta_p: ArrayLike,
    E: ArrayLike,
    cross_sign: ArrayLike = -1.0,
):
    """Compression + bending energy of one fingertip (Eq 5.4).

    ``P = pi E (d_n^3 / (3 cos^2 theta_p) + cross_sign d_n^2 d_t tan theta_p + d_n d_t^2)``.
    With ``d_t = 0`` it is Eq 2.14.  Eq 5.4 prints ``cross_sign = -1`` (the default); the
    two-finger Eq 5.5 prints ``(-1)^i`` for finger ``i`` -- pass an array to use it.  Energy is
    mirror-symmetric: ``P(d_n, d_t, theta_p) = P(d_n, -d_t, -theta_p)``.

    Parameters
    ----------
    d_n : array_like
        Normal displacement, m, ``>= 0``.
    d_t : array_like
        Tangential (bending) displacement, m, any finite value.
    theta_p : array_like
        Object orientation angle, rad, ``|theta_p| < pi/2``.
    E : array_like
        Young's modulus, Pa, ``> 0``.
    cross_sign : array_like, optional
        Sign of the cross term, ``+1`` or ``-1``.

    Returns
    -------
    float or ndarray
        Energy in J, shape ``broadcast(d_n, d_t, theta_p, E, cross_sign)``.
    """
    n, t, theta, e, sign = _bending_args(d_n, d_t, theta_p, E, cross_sign)
    cos2 = np.cos(theta) ** 2
    return _out(np.pi * e * (n**3 / (3 * cos2) + sign * n**2 * t * np.tan(theta) + n * t**2))


def bending_energy_gradient(
    d_n: ArrayLike,
    d_t: ArrayLike,
    theta_p: ArrayLike,
    E: ArrayLike,
    cross_sign: ArrayLike = -1.0,
) -> np.ndarray:
    """Gradient of :func:`bending_energy` with respect to ``(d_n, d_t, theta_p)``.

    ``dP/dd_n = pi E (d_n^2 / cos^2 + 2 s d_n d_t tan + d_t^2)``,
    ``dP/dd_t = pi E (s d_n^2 tan + 2 d_n d_t)``,
    ``dP/dtheta_p = pi E (2 d_n^3 tan / (3 cos^2) + s d_n^2 d_t / cos^2)`` with ``s`` the
    cross-term sign.  Same parameters as :func:`bending_energy`.

    Returns
    -------
    ndarray
        Shape ``broadcast(...) + (3,)``: ``[..., 0]`` in N (J/m), ``[..., 1]`` in N,
        ``[..., 2]`` in J/rad (N m).
    """
    n, t, theta, e, s = _bending_args(d_n, d_t, theta_p, E, cross_sign)
    sec2, tan = 1 / np.cos(theta) ** 2, np.tan(theta)
    parts = (
        n**2 * sec2 + 2 * s * n * t * tan + t**2,
        s * n**2 * tan + 2 * n * t,
        2 * n**3 * tan * sec2 / 3 + s * n**2 * t * sec2,
    )
    return np.stack(np.broadcast_arrays(*(np.pi * e * p for p in parts)), axis=-1)
