"""A-priori RK4 stability check of the chapter-5 model: every mode, including the finger/PID ones.

Classic RK4 multiplies a linear mode ``dy/dt = lambda y`` by ``R(h lambda)`` per step,
``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``; a decaying mode (Re lambda < 0) is integrated
stably only while ``|R(h lambda)| <= 1`` (on the negative real axis: ``|h lambda| <= 2.785``).

The check linearises the model's right-hand side (:func:`.model.csm_rhs`: CSM with
Baumgarte stabilisation and the PID of Eq 5.42) by central finite differences at a set of
probe states and takes the eigenvalues of the 20 x 20 Jacobian, so every mode is covered with
the couplings the constraints create: the joint inertia I_i, the PID gains Kp, Kd, Ki, the
contact stiffness 2 pi E d_n / cos^2 theta_p and bending stiffness, the viscosities c_n, c_t,
the deformation inertia and the object's mass and inertia. (The fastest physical mode of the
paper's hand is the finger damping mode: Kd and c_n acting on the joint inertia plus the
deformation inertia the constraints attach to the finger: |lambda| dt = 0.84 at Table 5.1,
2.42 at Kd = 17.5, 2.90 at Kd = 21, beyond the limit, and 3.85 at Kd = 28.)

Probe states (:func:`probe_states`): symmetric grasps at rest on both holonomic constraints
with both fingertips compressed to d_n = 0.2 a, 0.35 a and 0.5 a (4, 7 and 10 mm for the
paper's hand; 10 mm is the largest compression the environments accept and the contact
stiffness grows with d_n), contact angle 0. The contact angle changes the finger mode a little:
against the fastest finger rate along the paper's motions (linearised every 10 ms of a dt =
0.02 ms run) the probe states fall short by 0.9 % (Kd = 17.5), 1.3 % (gains x1.2 with object
mass x0.8, |lambda| dt = 2.755 at the probes, 2.79 at the theta_p = 42 deg of motion 7; at dt =
0.1 ms that run ends over-compressed), 3.5 % (finger inertia x0.8) and 4.2 % (M_deform = 0.1156
kg). A mode therefore counts as unstable if RK4 amplifies it at (1 + :data:`STEP_MARGIN`) dt, 5
% more than the step. Each eigenvalue is named after the coordinates that dominate its
eigenvector (angles weighted by the finger length to compare them with lengths); the Baumgarte
modes (-alpha, double, and -beta) are reported from their exact values.

Under ``integrator="ros2"`` (:mod:`softhand_env.physics.rosenbrock`) the check is the same in
spirit but exact for the method as implemented: the linearised map of one ROS2 step of (1 +
STEP_MARGIN) times each step size the schedule takes after its ramp, ``ros2_dt`` and twice it
(:func:`.rosenbrock.largest_step`) (central differences of :func:`.rosenbrock.ros2_step` at the
same probe states; it contains the method's own matrix W, not only the model's Jacobian) must
not amplify any mode, |mu| <= exp(h max Re lambda) for every eigenvalue mu of the 20 x 20 step
matrix, where lambda are the eigenvalues of the model's own linearisation there (their largest
real part is ~0: the neutral object mode), with a 1e-6 relative tolerance for the difference
quotients. ROS2 with the exact Jacobian is L-stable (:func:`ros2_amplification` is at most 1 on
the whole left half plane and 0 at infinity); the check guards the approximation in W. Each
step-matrix eigenvalue is reported as the rate lambda = log(mu) / h it integrates
(``Mode.eigenvalue``) with ``amplification = |mu|``. :func:`check_stability`,
:func:`stability_message`, :func:`warn_if_unstable` and :func:`check_randomization_ranges`
use the check of ``params.integrator``.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import product

import numpy as np

from softhand_env.physics.model import (
    DN_1,
    DT_1,
    N_DIAG,
    NQ,
    NY,
    TH_1,
    TH_OBJ,
    X_OBJ,
    Y_OBJ,
    csm_rhs,
    pack_params,
)
from softhand_env.physics.params import HandParams

#: Extent of classic RK4's stability region on the negative real axis (|h lambda| <= 2.785).
RK4_REAL_STABILITY = 2.785
#: Relative margin on the step: a mode counts as unstable if RK4 amplifies it at
#: (1 + STEP_MARGIN) dt. The probe states underestimate the fastest rate met along the paper's
#: motions by up to 4.2 % (measured, see the module docstring).
STEP_MARGIN = 0.05

#: Normal compressions of the probe states, as fractions of the fingertip radius a.
PROBE_DN_FRACTIONS = (0.2, 0.35, 0.5)

# mode names, by the coordinate group that dominates the eigenvector
_GROUPS = (
    ("finger joint (I, Kp, Kd)", (TH_1, TH_1 + 1)),
    ("object", (X_OBJ, Y_OBJ, TH_OBJ)),
    ("compression", (DN_1, DN_1 + 1)),
    ("bending", (DT_1, DT_1 + 1)),
)
HOLONOMIC = "holonomic (alpha)"
NON_HOLONOMIC = "non-holonomic (beta)"
PID_INTEGRAL = "PID integral (Ki)"


def ros2_amplification(z: complex | np.ndarray) -> np.ndarray:
    """|R(z)| of ROS2 with the exact Jacobian (gamma = 1 + 1/sqrt(2)) for ``z = h lambda``:
    ``R = 1 + 3/2 z a + 1/2 z a (1 + z a - 2 a)``, ``a = 1 / (1 - gamma z)``."""
    from softhand_env.physics.rosenbrock import GAMMA

    z = np.asarray(z, dtype=complex)
    a = 1.0 / (1.0 - GAMMA * z)
    return np.abs(1.0 + 1.5 * z * a + 0.5 * a * z * (1.0 + z * a - 2.0 * a))


def rk4_amplification(z: complex | np.ndarray) -> np.ndarray:
    """|R(z)| of classic RK4 for ``z = h lambda`` (dimensionless; > 1 grows per step)."""
    z = np.asarray(z, dtype=complex)
    return np.abs(1.0 + z * (1.0 + z * (0.5 + z * (1.0 / 6.0 + z / 24.0))))


@dataclass(frozen=True)
class Mode:
    """The least stable eigenvalue of one mode class over the probe states.

    Attributes
    ----------
    name : str
        Mode class (e.g. ``"finger joint (I, Kp, Kd)"``, ``"compression"``).
    eigenvalue : complex
        lambda (1/s).
    amplification : float
        |R((1 + STEP_MARGIN) dt lambda)| of RK4 (> 1: the mode grows numerically although it
        decays, or is within the margin of doing so).
    hdt : float
        |lambda| dt (dimensionless; 2.785 is the limit on the negative real axis).
    """

    name: str
    eigenvalue: complex
    amplification: float
    hdt: float

    bound: float | None = None

    @property
    def unstable(self) -> bool:
        """True if the integrator amplifies this decaying mode (|R| > 1 with Re lambda < 0);
        for a mode of a step map (``bound`` set): |mu| above ``bound``, the growth the model's
        own linearisation allows over the step, with the tolerance."""
        if self.bound is not None:
            return self.amplification > self.bound
        return self.eigenvalue.real < 0.0 and self.amplification > 1.0 + 1e-12


def probe_states(params: HandParams) -> list[tuple[np.ndarray, np.ndarray]]:
    """States (20,) and set-points (2,) at which the model is linearised (module docstring).

    Symmetric grasps: theta_obj = 0, x_obj = 0, both fingers at the angle where the fingertip
    is compressed by d_n (each of :data:`PROBE_DN_FRACTIONS` times a) against the object,
    d_t = 0, at rest, set-points equal to the finger angles. Compressions the finger cannot
    reach (no solution of the holonomic constraint) are left out.
    """
    r = math.hypot(params.L, params.d_fi)
    phi = math.atan2(params.d_fi, params.L)
    out = []
    for frac in PROBE_DN_FRACTIONS:
        d = frac * params.a
        # W_fi - (L sin t + d_fi cos t) = a - d + W_obj / 2 (right finger, C^H = 0 at x = 0)
        rhs = (params.W_fi - params.a + d - 0.5 * params.W_obj) / r
        if abs(rhs) > 1.0:
            continue
        t = math.asin(rhs) - phi
        y = np.zeros(NY)
        y[Y_OBJ] = params.L * math.cos(t) - params.d_fi * math.sin(t)
        y[TH_1] = y[TH_1 + 1] = t
        y[DN_1] = y[DN_1 + 1] = d
        out.append((y, np.array([t, t])))
    return out


def jacobian(params: HandParams, y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """d(dy/dt)/dy of :func:`~softhand_env.physics.model.csm_rhs` at (y, u) by central differences,
    shape (20, 20) (1/s and mixed units)."""
    prm = pack_params(params)
    J = np.empty((NY, NY))
    fp = np.empty(NY)
    fm = np.empty(NY)
    diag = np.empty(N_DIAG)
    for j in range(NY):
        e = (1e-7 if j < NQ else 1e-5) * max(1.0, abs(y[j]))
        yp = y.copy()
        ym = y.copy()
        yp[j] += e
        ym[j] -= e
        csm_rhs(yp, u, prm, fp, diag)
        csm_rhs(ym, u, prm, fm, diag)
        J[:, j] = (fp - fm) / (2.0 * e)
    return J


def _mode_name(vec: np.ndarray, params: HandParams) -> str:
    # weight angles by the finger length (m per rad) so that entries compare as lengths;
    # position and velocity parts both count
    w = np.ones(NQ)
    w[[TH_OBJ, TH_1, TH_1 + 1]] = params.L
    mag = np.abs(vec[:NQ]) * w + np.abs(vec[NQ : 2 * NQ]) * w
    if np.abs(vec[2 * NQ :]).max() * params.L > mag.max():
        return PID_INTEGRAL
    return max(_GROUPS, key=lambda g: max(mag[j] for j in g[1]))[0]


@functools.lru_cache(maxsize=512)
def rk4_modes(params: HandParams) -> dict[str, Mode]:
    """Least stable eigenvalue of each mode class over :func:`probe_states` (cached).

    Returns a dict mode name -> :class:`Mode`; the Baumgarte modes carry their exact
    eigenvalues -alpha (double root) and -beta.
    """
    dt = params.dt
    modes: dict[str, Mode] = {}

    def rank(mode: Mode) -> tuple[bool, float, float]:
        # the least stable: an amplified decaying mode (largest |R| first), else the fastest
        return (mode.unstable, mode.amplification if mode.unstable else 0.0, mode.hdt)

    def offer(name: str, lam: complex) -> None:
        amp = float(rk4_amplification(lam * dt * (1.0 + STEP_MARGIN)))
        mode = Mode(name, complex(lam), amp, abs(lam) * dt)
        if name not in modes or rank(mode) > rank(modes[name]):
            modes[name] = mode

    offer(HOLONOMIC, complex(-params.alpha))
    offer(NON_HOLONOMIC, complex(-params.beta))
    for y, u in probe_states(params):
        lams, vecs = np.linalg.eig(jacobian(params, y, u))
        for k, lam in enumerate(lams):
            if not np.isfinite(lam):
                continue
            # the Baumgarte roots: reported from their exact values above
            if abs(lam + params.alpha) < 0.05 * params.alpha or abs(lam + params.beta) < (
                0.05 * params.beta
            ):
                continue
            offer(_mode_name(vecs[:, k], params), complex(lam))
    return modes


#: Tolerance on |mu| of the ROS2 step matrix (difference quotients of the step map).
ROS2_TOLERANCE = 1e-6


def ros2_step_matrix(params: HandParams, y: np.ndarray, u: np.ndarray, h: float) -> np.ndarray:
    """d(step)/dy of one ROS2 step of ``h`` seconds at (y, u) by central differences, shape
    (20, 20) (:func:`softhand_env.physics.rosenbrock.ros2_step`)."""
    from softhand_env.physics.rosenbrock import ros2_step

    prm = pack_params(params)
    A = np.empty((NY, NY))
    for j in range(NY):
        e = (1e-7 if j < NQ else 1e-5) * max(1.0, abs(y[j]))
        yp = y.copy()
        ym = y.copy()
        yp[j] += e
        ym[j] -= e
        ros2_step(yp, u, prm, h)
        ros2_step(ym, u, prm, h)
        A[:, j] = (yp - ym) / (2.0 * e)
    return A


@functools.lru_cache(maxsize=512)
def ros2_modes(params: HandParams) -> dict[str, Mode]:
    """Least stable eigenvalue of each mode class of the ROS2 step map at (1 + STEP_MARGIN)
    times each step size a call takes after its ramp (``params.ros2_dt`` and the largest,
    :func:`.rosenbrock.largest_step`) over :func:`probe_states` (cached; module doc)."""
    from softhand_env.physics.rosenbrock import largest_step

    modes: dict[str, Mode] = {}
    excess: dict[str, float] = {}  # |mu| / bound of each kept mode (bounds differ by step)
    for y, u in probe_states(params):
        # the growth the model itself has at the probe state (a neutral mode: ~0)
        growth = max(0.0, float(np.linalg.eigvals(jacobian(params, y, u)).real.max()))
        for step in (params.ros2_dt, largest_step(params.ros2_dt)):
            h = step * (1.0 + STEP_MARGIN)
            bound = math.exp(growth * h) * (1.0 + ROS2_TOLERANCE)
            mus, vecs = np.linalg.eig(ros2_step_matrix(params, y, u, h))
            for k, mu in enumerate(mus):
                if not np.isfinite(mu):
                    continue
                amp = float(abs(mu))
                lam = complex(np.log(complex(mu)) / h) if amp > 0.0 else complex(-np.inf)
                mode = Mode(_mode_name(vecs[:, k], params), lam, amp, abs(lam) * step, bound)
                if amp / bound > excess.get(mode.name, -1.0):
                    modes[mode.name] = mode
                    excess[mode.name] = amp / bound
    return modes


def integrator_modes(params: HandParams) -> dict[str, Mode]:
    """:func:`rk4_modes` or :func:`ros2_modes`, as ``params.integrator`` says."""
    return ros2_modes(params) if params.integrator == "ros2" else rk4_modes(params)


def check_stability(params: HandParams) -> list[str]:
    """Names of the mode classes the integrator of ``params`` amplifies although they decay
    (RK4 at ``dt`` or ROS2 at ``ros2_dt``, with the step margin); empty if none."""
    return [name for name, mode in integrator_modes(params).items() if mode.unstable]


def rk4_stability_margins(params: HandParams) -> dict[str, float]:
    """|lambda| dt of the least stable eigenvalue of each mode class (RK4's limit on the
    negative real axis is 2.785; see :func:`check_rk4_stability` for complex ones)."""
    return {name: mode.hdt for name, mode in rk4_modes(params).items()}


def check_rk4_stability(params: HandParams) -> list[str]:
    """Names of the mode classes RK4 at ``params.dt`` amplifies although they decay, with the
    step margin :data:`STEP_MARGIN` (empty if none)."""
    return [name for name, mode in rk4_modes(params).items() if mode.unstable]


def stability_message(params: HandParams) -> str | None:
    """One-line description of the modes of ``params`` its integrator amplifies (None if all
    are stable)."""
    modes = [m for m in integrator_modes(params).values() if m.unstable]
    if not modes:
        return None
    if params.integrator == "ros2":
        from softhand_env.physics.rosenbrock import largest_step

        detail = ", ".join(f"{m.name}: |mu| = {m.amplification:.4f}" for m in modes)
        return (
            f"ROS2 step ros2_dt = {params.ros2_dt:g} s (steps up to "
            f"{largest_step(params.ros2_dt):g} s) amplifies the {detail} (linearised "
            f"step map, {STEP_MARGIN:.0%} margin); expect divergence (reduce ros2_dt)"
        )
    detail = ", ".join(f"{m.name}: |lambda| dt = {m.hdt:.2f}" for m in modes)
    limit = RK4_REAL_STABILITY / (1.0 + STEP_MARGIN)
    return (
        f"RK4 step dt = {params.dt:g} s is beyond the stability limit (|lambda| dt <= "
        f"{limit:.2f} on the real axis, {STEP_MARGIN:.0%} margin) of the {detail}; "
        f"expect divergence (reduce dt, or the gains/stiffness that set the mode)"
    )


def warn_if_unstable(params: HandParams, stacklevel: int = 2, error: bool = False) -> None:
    """Warn (``RuntimeWarning``) or, with ``error=True``, raise ``ValueError`` naming the modes
    beyond the stability limit of the integrator of ``params`` (:func:`stability_message`)."""
    message = stability_message(params)
    if message is None:
        return
    if error:
        raise ValueError(message)
    warnings.warn(message, RuntimeWarning, stacklevel=stacklevel + 1)


def check_randomization_ranges(
    base: HandParams,
    groups: Mapping[str, Sequence[str]],
    half_widths: Mapping[str, float],
) -> None:
    """Refuse randomisation ranges whose extremes leave the integrator's stable region.

    Each keyword k scales the fields ``groups[k]`` together by a factor in
    ``[1 - half_widths[k], 1 + half_widths[k]]``; every corner of that box (all keywords at
    one of their extremes) is checked with :func:`check_stability` (RK4 or ROS2, as
    ``base.integrator`` says).

    Parameters
    ----------
    base : HandParams
        Parameters the factors multiply.
    groups : mapping keyword -> sequence of HandParams field names
        e.g. ``{"rand_gains": ("Kp", "Kd", "Ki"), "rand_mass": ("M_obj",)}``.
    half_widths : mapping keyword -> float
        Relative half-widths in [0, 1); keywords with 0 (or missing) are not varied.

    Raises
    ------
    ValueError
        Naming the keyword(s), the corner, the unstable mode and the largest half-width of the
        first offending keyword that keeps that corner stable (the others at their extremes).
    """
    active = [k for k in groups if half_widths.get(k, 0.0) > 0.0]
    if not active:
        return

    def corner(signs: Sequence[float], scale: Mapping[str, float]) -> HandParams:
        changes: dict[str, float] = {}
        for k, s in zip(active, signs, strict=True):
            for field in groups[k]:
                changes[field] = float(getattr(base, field)) * (1.0 + s * scale[k])
        return base.replace(**changes)

    widths = {k: float(half_widths[k]) for k in active}
    for signs in product((-1.0, 1.0), repeat=len(active)):
        params = corner(signs, widths)
        unstable = check_stability(params)
        if not unstable:
            continue
        # the largest half-width of one keyword that makes this corner stable on its own
        # (bisection, the others at their extremes)
        limit_text = "no single keyword makes it stable"
        for k in active:
            if check_stability(corner(signs, {**widths, k: 0.0})):
                continue
            lo, hi = 0.0, widths[k]
            for _ in range(30):
                mid = 0.5 * (lo + hi)
                if check_stability(corner(signs, {**widths, k: mid})):
                    hi = mid
                else:
                    lo = mid
            limit_text = f"{k} <= {lo:.3g} keeps it stable"
            break
        where = ", ".join(
            f"{k} {'+' if s > 0 else '-'}{widths[k]:g}" for k, s in zip(active, signs, strict=True)
        )
        mode = integrator_modes(params)[unstable[0]]
        if params.integrator == "ros2":
            raise ValueError(
                f"randomisation range leaves ROS2's stable region at ros2_dt = "
                f"{params.ros2_dt:g} s: at ({where}) the {mode.name} mode has |mu| = "
                f"{mode.amplification:.4f} > 1; {limit_text}"
            )
        raise ValueError(
            f"randomisation range leaves RK4's stable region at dt = {params.dt:g} s: at "
            f"({where}) the {mode.name} mode has |lambda| dt = {mode.hdt:.2f} (limit "
            f"{RK4_REAL_STABILITY / (1.0 + STEP_MARGIN):.2f} on the real axis); {limit_text}"
        )


__all__ = [
    "Mode",
    "RK4_REAL_STABILITY",
    "STEP_MARGIN",
    "ROS2_TOLERANCE",
    "check_randomization_ranges",
    "check_rk4_stability",
    "check_stability",
    "integrator_modes",
    "jacobian",
    "probe_states",
    "rk4_amplification",
    "rk4_modes",
    "rk4_stability_margins",
    "ros2_amplification",
    "ros2_modes",
    "ros2_step_matrix",
    "stability_message",
    "warn_if_unstable",
]
