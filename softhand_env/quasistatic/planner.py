"""Open-loop finger-angle plans from the quasi-static LMEE model (:mod:`softhand_env.quasistatic`).

Both planners start from the grasp: the open hand closes symmetrically to the grasp angle
(operation 1 of Sec. 4.3; returned separately as :attr:`Plan.approach`) and the plan proper
(:attr:`Plan.setpoints`, row 0 = the grasp) is a straight line in finger-angle space sampled
every ``step`` rad per finger, so consecutive set-points differ by at most ``step``:

* :func:`plan_translation` rotates both fingers together, (g + phi, g - phi), until the
  object's x reaches the target; phi > 0 (counter-clockwise) moves the object to -x. The
  object's orientation then follows from the model (theta_obj is about -phi).
* :func:`plan_pose` moves the end point (theta_1, theta_2) of the straight line freely, so
  that both x and theta_obj reach their targets; the reachable set is a band around the
  translation plans (theta_obj within a few degrees of the value that plain rotation gives
  at that x), bounded by the finger-angle and squeeze limits.

Both verify the plan by running the set-points through :func:`~softhand_env.quasistatic.solve_path`
from the grasp state and raise ``ValueError`` for unreachable targets. Because the model is
path-dependent, the prediction holds for the set-points *as planned*, executed in order from
the grasp; the dynamic environment adds gravity and PID lag, so expect deviations there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from softhand_env.physics.params import HandParams
from softhand_env.quasistatic import (
    DEFAULT_STEP,
    QuasiStaticPath,
    QuasiStaticState,
    initial_state,
    linear_path,
    resolve_params,
    solve_path,
)

#: Default grasp angle of both fingers (rad): 6 deg.
DEFAULT_GRASP = math.radians(6.0)


@dataclass(frozen=True)
class Plan:
    """A finger-angle set-point sequence and the quasi-static prediction along it.

    Attributes
    ----------
    setpoints : ndarray, shape (K, 2)
        (theta_1, theta_2) set-points in rad; row 0 is the grasp, increments <= ``step``.
    approach : ndarray, shape (M, 2)
        Set-points closing the open hand to the grasp (operation 1), rad; its last row equals
        ``setpoints[0]``.
    predicted : QuasiStaticPath
        Quasi-static states along ``setpoints`` starting from ``grasp_state``.
    grasp_state : QuasiStaticState
        State at the grasp reached through ``approach``.
    target : ndarray, shape (2,)
        Target (x in m, theta_obj in rad; NaN when not targeted).
    error : ndarray, shape (2,)
        Predicted final minus target (m, rad; NaN when not targeted).
    """

    setpoints: np.ndarray
    approach: np.ndarray
    predicted: QuasiStaticPath
    grasp_state: QuasiStaticState
    target: np.ndarray
    error: np.ndarray

    @property
    def final(self) -> QuasiStaticState:
        """Predicted state after the last set-point."""
        return self.predicted.final

    @property
    def n_base_violation(self) -> int:
        """Planned increments at which a contact passes the fingertip base."""
        return self.predicted.n_base_violation


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a finite float (got {value!r})")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite (got {v!r})")
    return v


def grasp_path(
    params: HandParams | None = None, grasp_angle: float = DEFAULT_GRASP, step: float = DEFAULT_STEP
) -> QuasiStaticPath:
    """Quasi-static closing of the open hand to (grasp_angle, grasp_angle) (operation 1).

    Raises
    ------
    ValueError
        If the grasp angle does not squeeze the object (fingers open beyond contact).
    """
    p = resolve_params(params)
    g = _finite("grasp_angle", grasp_angle)
    st = initial_state(p)
    if g <= st.theta[0]:
        raise ValueError(
            f"grasp_angle = {g:.4g} rad must exceed the first-touch angle {st.theta[0]:.4g} rad"
        )
    return solve_path(linear_path(st.theta, np.array([g, g]), step), p, st)


def _run(grasp: QuasiStaticState, end: np.ndarray, p: HandParams, step: float) -> QuasiStaticPath:
    """Solve the straight path grasp -> end sampled as :func:`linear_path` does."""
    return solve_path(linear_path(grasp.theta, end, step), p, grasp, max_step=step * (1 + 1e-9))


def _make_plan(approach, grasp, end, p, step, target):
    predicted = _run(grasp, end, p, step)
    setpoints = predicted.theta
    fin = predicted.final
    err = np.array([fin.x - target[0], fin.theta_obj - target[1]])
    return Plan(setpoints, approach, predicted, grasp, np.asarray(target, dtype=float), err)


def plan_translation(
    target_x: float,
    params: HandParams | None = None,
    grasp_angle: float = DEFAULT_GRASP,
    *,
    step: float = DEFAULT_STEP,
    max_rotation: float = math.radians(20.0),
    tol: float = 1e-6,
    allow_base_violation: bool = True,
) -> Plan:
    """Set-points that carry the object to x = ``target_x`` by rotating both fingers together.

    Parameters
    ----------
    target_x : float
        Target object x in Sigma_R (m).
    params : HandParams, optional
        Default ``load_hand_params("paper_ch4")``.
    grasp_angle : float
        Grasp angle of both fingers (rad), default 6 deg.
    step : float
        Largest set-point increment per finger (rad), default 0.1 deg.
    max_rotation : float
        Largest rotation |phi| (rad) allowed, default 20 deg (the paper's range).
    tol : float
        Required |predicted x - target_x| (m) of the returned plan.
    allow_base_violation : bool
        If False, raise when the plan needs contacts beyond the fingertip base (where the
        closed-form energy of Eq 2.14 over-predicts).

    Returns
    -------
    Plan
        ``setpoints[k] = (g + phi_k, g - phi_k)`` from phi = 0 to the solved phi.

    Raises
    ------
    ValueError
        Non-finite arguments, or a target outside the x range reachable with
        |phi| <= max_rotation (the message gives that range).
    """
    return _plan_rotation(
        "x", target_x, params, grasp_angle, step, max_rotation, tol, allow_base_violation
    )


def plan_reorientation(
    target_theta: float,
    params: HandParams | None = None,
    grasp_angle: float = DEFAULT_GRASP,
    *,
    step: float = DEFAULT_STEP,
    max_rotation: float = math.radians(20.0),
    tol: float = 1e-7,
    allow_base_violation: bool = True,
) -> Plan:
    """Set-points that turn the object to theta_obj = ``target_theta`` (rad) by rotating both
    fingers together; the object's x follows from the model. Arguments as
    :func:`plan_translation` (``tol`` in rad)."""
    return _plan_rotation(
        "theta_obj", target_theta, params, grasp_angle, step, max_rotation, tol,
        allow_base_violation,
    )


def _plan_rotation(
    quantity: str,
    target: float,
    params: HandParams | None,
    grasp_angle: float,
    step: float,
    max_rotation: float,
    tol: float,
    allow_base_violation: bool,
) -> Plan:
    """Solve the common finger rotation phi at which ``quantity`` ("x" or "theta_obj") of the
    quasi-static path reaches ``target`` (see :func:`plan_translation`)."""
    name = "target_x" if quantity == "x" else "target_theta"
    unit = "m" if quantity == "x" else "rad"
    p = resolve_params(params)
    xt = _finite(name, target)
    max_rot = _finite("max_rotation", max_rotation)
    step = _finite("step", step)
    tol = _finite("tol", tol)
    if not 0 < max_rot < math.pi / 2 or step <= 0 or tol <= 0:
        raise ValueError("max_rotation must be in (0, pi/2); step and tol must be > 0")
    gp = grasp_path(p, grasp_angle, step)
    grasp = gp.final
    g = grasp.theta
    rot = lambda phi: g + np.array([phi, -phi])  # noqa: E731
    # scan both directions; the quantity is sampled on the set-point grid
    scans = []
    for sign in (1.0, -1.0):
        th = linear_path(g, rot(sign * max_rot), step)
        scans.append((sign, solve_path(th, p, grasp, on_failure="truncate")))
    xs = np.concatenate([getattr(s, quantity) for _, s in scans])
    lo, hi = float(xs.min()), float(xs.max())
    if not lo - tol <= xt <= hi + tol:
        raise ValueError(
            f"{name} = {xt:.6g} {unit} is not reachable by rotating both fingers by at most "
            f"{math.degrees(max_rot):.3g} deg from the {math.degrees(g[0]):.3g} deg grasp: "
            f"reachable {quantity} is [{lo:.6g}, {hi:.6g}] {unit}"
            + "".join(f"; the {'CCW' if sg > 0 else 'CW'} rotation stops early: {s.status}"
                      for sg, s in scans if s.status != "ok")
        )
    x0 = getattr(grasp, quantity)
    first = getattr(scans[0][1], quantity)
    _, scan = scans[0] if (xt - x0) * (first[-1] - x0) > 0 else scans[1]
    phis = 0.5 * (scan.theta[:, 0] - scan.theta[:, 1])  # g[0] == g[1]
    f = getattr(scan, quantity) - xt
    k = int(np.argmax(np.sign(f) != np.sign(f[0]))) if f[0] != 0 else 0
    if k == 0:
        phi = 0.0 if abs(f[0]) <= tol else float(phis[-1])
    else:
        # bracketing interval [phis[k-1], phis[k]]; Brent with the exact path end points
        from scipy.optimize import brentq

        def resid(ph: float) -> float:
            return float(getattr(_run(grasp, rot(ph), p, step), quantity)[-1] - xt)

        a_, b_ = float(phis[k - 1]), float(phis[k])
        phi = a_ if abs(f[k - 1]) <= tol * 1e-3 else brentq(resid, a_, b_, xtol=1e-13)
    target_pair = (xt, math.nan) if quantity == "x" else (math.nan, xt)
    plan = _make_plan(gp.theta, grasp, rot(phi), p, step, target_pair)
    err = plan.error[0] if quantity == "x" else plan.error[1]
    if not abs(err) <= tol:
        raise ValueError(
            f"{name} = {xt:.6g} {unit}: the planned sequence ends at "
            f"{quantity} = {getattr(plan.final, quantity):.6g} {unit} "
            f"(error {err:.3g} {unit} > tol {tol:.3g} {unit})"
        )
    if not allow_base_violation and plan.n_base_violation:
        raise ValueError(
            f"{name} = {xt:.6g} {unit} needs {plan.n_base_violation} increments with a contact "
            "beyond the fingertip base (allow_base_violation=False)"
        )
    return plan


def plan_pose(
    target_x: float,
    target_theta: float,
    params: HandParams | None = None,
    grasp_angle: float = DEFAULT_GRASP,
    *,
    step: float = DEFAULT_STEP,
    max_angle: float = math.radians(45.0),
    squeeze_limits: tuple[float, float] | None = None,
    tol_x: float = 1e-6,
    tol_theta: float = 1e-5,
    max_iter: int = 40,
    allow_base_violation: bool = True,
) -> Plan:
    """Set-points that bring the object to (x, theta_obj) along a straight finger path.

    The unknowns are the end finger angles (theta_1, theta_2); the straight path from the
    grasp to them is solved quasi-statically and the end pose matched to the target by a
    damped Newton iteration with a finite-difference Jacobian (starting from the
    :func:`plan_translation` solution for ``target_x``).

    Parameters
    ----------
    target_x : float
        Target object x (m).
    target_theta : float
        Target object orientation (rad, counter-clockwise).
    params, grasp_angle, step, allow_base_violation
        As in :func:`plan_translation`.
    max_angle : float
        Largest |theta_i| (rad) of the end point.
    squeeze_limits : (float, float), optional
        Allowed (min, max) compression d_i (m) along the planned path; default
        (1 mm, 0.6 a) keeps a firm grasp and stays well inside the fingertip.
    tol_x, tol_theta : float
        Required end-pose accuracy (m, rad).
    max_iter : int
        Newton iterations.

    Returns
    -------
    Plan

    Raises
    ------
    ValueError
        Non-finite arguments, or no straight path from the grasp reaches the target within
        the limits (the message says which limit or that Newton did not converge).
    """
    p = resolve_params(params)
    xt = _finite("target_x", target_x)
    tt = _finite("target_theta", target_theta)
    max_angle = _finite("max_angle", max_angle)
    dmin, dmax = (1e-3, 0.6 * p.a) if squeeze_limits is None else squeeze_limits
    dmin, dmax = _finite("squeeze_limits[0]", dmin), _finite("squeeze_limits[1]", dmax)
    if not 0 <= dmin < dmax < p.a:
        raise ValueError(f"squeeze_limits must satisfy 0 <= min < max < a (got {dmin}, {dmax})")
    base = plan_translation(xt, p, grasp_angle, step=step, max_rotation=max_angle,
                            tol=max(tol_x, 1e-6))
    grasp = base.grasp_state
    u = base.setpoints[-1].copy()
    scale = np.array([1.0 / p.a, 1.0])  # residual in (x / a, theta): both dimensionless

    def evaluate(end: np.ndarray) -> np.ndarray | None:
        if np.max(np.abs(end)) > max_angle + math.radians(10):
            return None
        try:
            path = _run(grasp, end, p, step)
        except (ValueError, RuntimeError):
            return None
        return (np.array([path.x[-1], path.theta_obj[-1]]) - (xt, tt)) * scale

    r = evaluate(u)
    if r is None:
        raise ValueError("plan_pose: the translation plan used as a start point failed")
    h = 1e-6
    for _ in range(max_iter):
        if abs(r[0]) <= tol_x * scale[0] * 0.1 and abs(r[1]) <= tol_theta * 0.1:
            break
        Jm = np.empty((2, 2))
        ok = True
        for j in range(2):
            e = np.zeros(2)
            e[j] = h
            rp, rm = evaluate(u + e), evaluate(u - e)
            if rp is None or rm is None:
                ok = False
                break
            Jm[:, j] = (rp - rm) / (2 * h)
        if not ok or abs(np.linalg.det(Jm)) < 1e-14:
            break
        du = -np.linalg.solve(Jm, r)
        lam = 1.0
        while lam > 1e-4:
            trial = u + lam * du
            rt = evaluate(trial)
            if rt is not None and np.linalg.norm(rt) < np.linalg.norm(r):
                u, r = trial, rt
                break
            lam *= 0.5
        else:
            break
    if not (abs(r[0]) <= tol_x * scale[0] and abs(r[1]) <= tol_theta):
        raise ValueError(
            f"target pose (x = {xt:.6g} m, theta = {tt:.6g} rad) is not reachable by a straight "
            f"finger path from the {math.degrees(grasp.theta[0]):.3g} deg grasp (closest: "
            f"error {r[0] / scale[0]:.3g} m, {r[1]:.3g} rad)"
        )
    if np.max(np.abs(u)) > max_angle:
        raise ValueError(
            f"target pose (x = {xt:.6g} m, theta = {tt:.6g} rad) needs finger angles "
            f"{np.degrees(u).round(2).tolist()} deg beyond max_angle = "
            f"{math.degrees(max_angle):.3g} deg"
        )
    plan = _make_plan(base.approach, grasp, u, p, step, (xt, tt))
    d = plan.predicted.d
    if d.min() < dmin or d.max() > dmax:
        raise ValueError(
            f"target pose (x = {xt:.6g} m, theta = {tt:.6g} rad) needs fingertip compressions "
            f"in [{d.min():.3g}, {d.max():.3g}] m outside squeeze_limits = "
            f"({dmin:.3g}, {dmax:.3g}) m"
        )
    if not (abs(plan.error[0]) <= tol_x and abs(plan.error[1]) <= tol_theta):
        raise ValueError(
            f"target pose: the planned sequence misses by {plan.error.tolist()} (m, rad)"
        )
    if not allow_base_violation and plan.n_base_violation:
        raise ValueError(
            f"target pose needs {plan.n_base_violation} increments with a contact beyond the "
            "fingertip base (allow_base_violation=False)"
        )
    return plan
