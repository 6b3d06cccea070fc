"""The handling process of Sec. 4.3 on the quasi-static model: paths, runs and key numbers.

:func:`handling_path` builds the finger-angle path of the seven operations (close, rotate
+20 deg, -40 deg, +40 deg, cycles, back to the grasp, open), :func:`handling_process` solves it
with :func:`~softhand_env.quasistatic.solver.solve_path`, :func:`handling_summary` extracts the
numbers the paper's figures compare. Conventions (the direction of "counter-clockwise" for each
finger, phi = (theta_1 - theta_2)/2): ``docs/quasistatic.md``. Units are SI (m, rad).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from softhand_env.physics.params import HandParams
from softhand_env.quasistatic.solver import (
    DEFAULT_STEP,
    QuasiStaticPath,
    initial_state,
    linear_path,
    resolve_params,
    solve_path,
)

#: Grasp angles of Sec. 4.3 (rad): 2.4 to 7.2 deg in 1.2 deg steps.
PAPER_GRASP_ANGLES = tuple(math.radians(g) for g in (2.4, 3.6, 4.8, 6.0, 7.2))
#: Finger rotation of operations 2-6 (rad): 20 deg.
PAPER_ROTATION = math.radians(20.0)


def handling_path(
    grasp_angle: float,
    step: float = DEFAULT_STEP,
    rotation: float = PAPER_ROTATION,
    cycles: int = 3,
    theta_start: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Finger-angle path of the Sec. 4.3 handling process and its operation numbers.

    Parameters
    ----------
    grasp_angle : float
        Grasp angle g (rad) reached by both fingers in operation 1.
    step : float
        Increment (rad) per finger.
    rotation : float
        Rotation of operation 2 (rad); operations 3/4 rotate by 2 * rotation.
    cycles : int
        Repetitions of operations 3 and 4 in operation 5 (paper: 3).
    theta_start : float
        Finger angle of the open hand (rad; 0 for the paper's parameters).

    Returns
    -------
    theta : ndarray, shape (N, 2)
        (theta_1, theta_2) in rad; counter-clockwise rotation of both fingers by phi is
        (g + phi, g - phi).
    op : ndarray of int, shape (N,)
        Operation number 1-7 of each row (row 0, the open hand, is labelled 1).
    """
    for name, val in (("grasp_angle", grasp_angle), ("step", step), ("rotation", rotation)):
        if not isinstance(val, (int, float, np.floating)) or not math.isfinite(val):
            raise ValueError(f"{name} must be a finite float (rad) (got {val!r})")
    if not 0 < step <= math.radians(1.0):
        raise ValueError(f"step must be in (0, 1 deg] (got {step!r} rad)")
    if not isinstance(cycles, (int, np.integer)) or cycles < 0:
        raise ValueError(f"cycles must be a non-negative int (got {cycles!r})")
    g = float(grasp_angle)
    t0 = float(theta_start)
    grasp = np.array([g, g])
    rot = lambda phi: np.array([g + phi, g - phi])  # noqa: E731
    segments = [(1, np.array([t0, t0]), grasp), (2, grasp, rot(rotation))]
    segments.append((3, rot(rotation), rot(-rotation)))
    segments.append((4, rot(-rotation), rot(rotation)))
    for _ in range(cycles):
        segments.append((5, rot(rotation), rot(-rotation)))
        segments.append((5, rot(-rotation), rot(rotation)))
    segments.append((6, rot(rotation), grasp))
    segments.append((7, grasp, np.array([t0, t0])))
    rows = [segments[0][1][None, :]]
    ops = [np.array([1])]
    for op, a0, a1 in segments:
        seg = linear_path(a0, a1, step)[1:]
        rows.append(seg)
        ops.append(np.full(seg.shape[0], op))
    return np.vstack(rows), np.concatenate(ops)


def handling_process(
    grasp_angle: float,
    params: HandParams | None = None,
    step: float = DEFAULT_STEP,
    *,
    rotation: float = PAPER_ROTATION,
    cycles: int = 3,
    scheme: str = "trapezoid",
) -> QuasiStaticPath:
    """Simulate the handling process of Sec. 4.3 for one grasp angle.

    Parameters
    ----------
    grasp_angle : float
        Grasp angle (rad); the paper uses 2.4, 3.6, 4.8, 6.0, 7.2 deg (PAPER_GRASP_ANGLES).
    params : HandParams, optional
        Default ``load_hand_params("paper_ch4")``.
    step : float
        Finger-angle increment (rad), default 0.1 deg.
    rotation, cycles, scheme
        See :func:`handling_path` and :func:`solve_path`.

    Returns
    -------
    QuasiStaticPath
        With ``op`` holding the operation number (1-7) of each row and ``grasp_angle`` set.
        The x end points of the +20 deg and -40 deg operations are rows ``end_of(2)`` and
        ``end_of(3)``.
    """
    p = resolve_params(params)
    st = initial_state(p)
    theta, op = handling_path(grasp_angle, step, rotation, cycles, float(st.theta[0]))
    path = solve_path(theta, p, st, scheme=scheme, max_step=max(step, DEFAULT_STEP) * 1.0001)
    return dataclasses.replace(path, op=op, grasp_angle=float(grasp_angle))


def rotation_angle(path: QuasiStaticPath) -> np.ndarray:
    """(N,) counter-clockwise finger rotation phi = (theta_1 - theta_2)/2 (rad)."""
    return 0.5 * (path.theta[:, 0] - path.theta[:, 1])


def handling_summary(paths: list[QuasiStaticPath]) -> dict[str, np.ndarray]:
    """Key numbers of handling-process runs (one per grasp angle), SI units.

    Returns a dict of arrays over the runs: ``grasp_angle``, ``x_after_ccw`` (end of op 2),
    ``x_after_cw`` (end of op 3), ``y_grasp`` (end of op 1), ``drift_xy`` and
    ``drift_theta`` (end of op 6 minus end of op 1: m and rad), ``n_base_violation``,
    ``max_constraint_residual`` (m), ``max_kkt_residual`` (non-degenerate rows) and
    ``min_reduced_hessian``.
    """
    out: dict[str, list[float]] = {k: [] for k in (
        "grasp_angle", "x_after_ccw", "x_after_cw", "y_grasp", "drift_xy", "drift_theta",
        "n_base_violation", "max_constraint_residual", "max_kkt_residual",
        "min_reduced_hessian")}
    for pth in paths:
        i1, i2, i3, i6 = pth.end_of(1), pth.end_of(2), pth.end_of(3), pth.end_of(6)
        out["grasp_angle"].append(pth.grasp_angle)
        out["x_after_ccw"].append(pth.x[i2])
        out["x_after_cw"].append(pth.x[i3])
        out["y_grasp"].append(pth.y[i1])
        out["drift_xy"].append(math.hypot(pth.x[i6] - pth.x[i1], pth.y[i6] - pth.y[i1]))
        out["drift_theta"].append(abs(pth.theta_obj[i6] - pth.theta_obj[i1]))
        out["n_base_violation"].append(pth.n_base_violation)
        out["max_constraint_residual"].append(float(np.max(pth.constraint_residual)))
        out["max_kkt_residual"].append(float(np.nanmax(pth.kkt_residual)))
        nd = ~pth.degenerate
        out["min_reduced_hessian"].append(float(np.min(pth.reduced_hessian[nd])))
    return {k: np.asarray(v) for k, v in out.items()}
