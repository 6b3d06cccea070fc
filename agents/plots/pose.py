"""Drawing of the ``SoftHandPose-v0`` policy-comparison figures (:mod:`agents.pose_figures`).

* :func:`plot_reachable`: one panel per policy, the outcome of one episode per goal on a grid
  over (x*, theta*), categorical colours, the task's goal range as a dashed box.
* :func:`plot_manoeuvre`: one column per policy for one goal: the finger set-point path in
  (rotate, squeeze) coordinates, and the object x and theta over time.

Plain matplotlib ``Figure`` objects on the Agg canvas (no pyplot state, no display needed);
the functions take arrays, not environments, so that the figures can be redrawn from
``reachable.npz``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from softhand_env.physics.failure import REASONS

#: Every outcome an episode can have: success, ran to the time limit out of tolerance, or the
#: env's ``termination_reason`` (the physics failures, then the contact checks).
OUTCOMES: tuple[str, ...] = ("success", "time", *REASONS, "tension", "slip")

#: Colour of each outcome (the same in every panel).
OUTCOME_COLORS: dict[str, str] = {
    "success": "#2ca02c",
    "time": "#d0d0d0",
    "nonfinite_state": "#000000",
    "constraint_violation": "#e377c2",
    "overcompressed": "#d62728",
    "grasp_lost": "#8c564b",
    "contact_past_base": "#1f77b4",
    "tension": "#9467bd",
    "slip": "#ff7f0e",
}

#: theta change per mm of x along the straight rotation of both fingers (deg/mm): the
#: rotation-coupled line theta* = COUPLING x* that needs no rolling loop (the constant of
#: :class:`agents.scripted.loop_plan.LoopPlanPolicy`).
COUPLING_DEG_PER_MM = 0.77


def describe(outcome: str) -> str:
    """Legend text of an outcome."""
    return "time limit, out of tolerance" if outcome == "time" else outcome


def _canvas(width: float, height: float) -> Any:
    """A Figure on the Agg canvas (inches)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig


def in_box(goal_x_mm: np.ndarray, goal_theta_deg: np.ndarray, box_mm: float,
           box_deg: float) -> np.ndarray:
    """bool (G_theta, G_x): grid goals inside the task's range |x*| <= box_mm (mm) and
    |theta*| <= box_deg (deg); axes (G_x,) mm and (G_theta,) deg."""
    eps = 1e-9
    return ((np.abs(goal_theta_deg)[:, None] <= box_deg + eps)
            & (np.abs(goal_x_mm)[None, :] <= box_mm + eps))


def rate(success: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Success rate of the entries of ``success`` (bool array) selected by ``mask`` (NaN if
    none)."""
    picked = success if mask is None else success[mask]
    return float(np.mean(picked)) if picked.size else float("nan")


def _edges(centers: np.ndarray) -> np.ndarray:
    """Cell edges (G + 1,) around increasing, equally spaced cell centres (G,)."""
    half = (centers[1] - centers[0]) / 2 if len(centers) > 1 else 0.5
    return np.concatenate([centers - half, [centers[-1] + half]])


def plot_reachable(
    path: Path,
    labels: Sequence[str],
    outcome: np.ndarray,
    goal_x_mm: np.ndarray,
    goal_theta_deg: np.ndarray,
    box_mm: float,
    box_deg: float,
    title: str,
    marked_goal: tuple[float, float] | None = None,
) -> Any:
    """Write the reachable-set PNG; returns the Figure.

    Parameters
    ----------
    path : Path
        PNG file.
    labels : sequence of P str
        Policy names (panel titles).
    outcome : ndarray of str, shape (P, G_theta, G_x)
        Outcome of each episode (one of :data:`OUTCOMES`; other strings get a neutral colour).
    goal_x_mm : ndarray, shape (G_x,)
        Grid of x* (mm), increasing.
    goal_theta_deg : ndarray, shape (G_theta,)
        Grid of theta* (deg), increasing.
    box_mm, box_deg : float
        The task's goal range (mm, deg): drawn as a dashed box, its success rate in the title.
    title : str
        Figure title.
    marked_goal : (x* mm, theta* deg), optional
        A goal to mark (the manoeuvre figure's).
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle

    n = len(labels)
    present = [o for o in OUTCOMES if np.any(outcome == o)]
    present += sorted(set(np.unique(outcome).tolist()) - set(OUTCOMES))
    codes = np.zeros(outcome.shape, dtype=np.int64)
    for k, name in enumerate(present):
        codes[outcome == name] = k
    cmap = ListedColormap([OUTCOME_COLORS.get(o, "#ffff99") for o in present])
    box = in_box(goal_x_mm, goal_theta_deg, box_mm, box_deg)
    fig = _canvas(max(4.6 * n + 0.4, 7.5), 5.4)
    axes = np.atleast_1d(fig.subplots(1, n, sharex=True, sharey=True, squeeze=False)[0])
    xe, te = _edges(goal_x_mm), _edges(goal_theta_deg)
    for p, ax in enumerate(axes):
        ax.pcolormesh(xe, te, codes[p], cmap=cmap, vmin=-0.5, vmax=len(present) - 0.5)
        ax.add_patch(Rectangle((-box_mm, -box_deg), 2 * box_mm, 2 * box_deg, fill=False,
                               ls="--", lw=1.5, ec="k"))
        xs = np.array([xe[0], xe[-1]])
        ax.plot(xs, COUPLING_DEG_PER_MM * xs, ":", color="k", lw=1)
        if marked_goal is not None:
            ax.plot(*marked_goal, marker="*", ms=12, mfc="w", mec="k", ls="none")
        ax.set_xlim(xe[0], xe[-1])
        ax.set_ylim(te[0], te[-1])
        ax.set_aspect("auto")
        success = outcome[p] == "success"
        ax.set_title(f"{labels[p]}\nsuccess: task box {100 * rate(success, box):.1f} % "
                     f"({int(box.sum())} goals), grid {100 * rate(success):.1f} % "
                     f"({success.size})", fontsize=9)
        ax.set_xlabel("goal x* (mm)")
    axes[0].set_ylabel("goal theta* (deg)")
    handles: list[Any] = [Patch(fc=OUTCOME_COLORS.get(o, "#ffff99"), ec="k", lw=0.5,
                                label=describe(o)) for o in present]
    handles.append(Line2D([], [], ls="--", color="k", label=f"task range (+-{box_mm:g} mm, "
                          f"+-{box_deg:g} deg)"))
    handles.append(Line2D([], [], ls=":", color="k",
                          label=f"straight rotation: theta* = {COUPLING_DEG_PER_MM} x*"))
    if marked_goal is not None:
        handles.append(Line2D([], [], marker="*", ms=10, mfc="w", mec="k", ls="none",
                              label="manoeuvre goal"))
    ncol = 2 if n == 1 else 4
    rows = -(-len(handles) // ncol)
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.02 + 0.045 * rows * 5.4 / fig.get_figheight(), 1, 1))
    fig.savefig(path, dpi=100)
    return fig


@dataclass
class Manoeuvre:
    """One episode of the manoeuvre figure (SI units as the env reports them).

    Attributes
    ----------
    label : str
        Policy name.
    dt : float
        Control period (s).
    setpoint : ndarray, shape (K+1, 2)
        Finger set-points (u1, u2) in rad after the reset and after every step.
    pose : ndarray, shape (K+1, 3)
        Object (x, y, theta) in m, m, rad, at the same times.
    goal : (x* in m, theta* in rad)
    outcome : str
        One of :data:`OUTCOMES`.
    """

    label: str
    dt: float
    setpoint: np.ndarray
    pose: np.ndarray
    goal: tuple[float, float]
    outcome: str


def rotate_squeeze(setpoint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rotate, squeeze) in deg, each (K,), of set-points (K, 2) in rad: rotate = (u1 - u2)/2,
    squeeze = (u1 + u2)/2."""
    u = np.degrees(np.asarray(setpoint, dtype=np.float64))
    return (u[:, 0] - u[:, 1]) / 2, (u[:, 0] + u[:, 1]) / 2


def signed_area(x: np.ndarray, y: np.ndarray) -> float:
    """Signed area enclosed by the path (x, y), each (K,), closed from its end back to its
    start (shoelace; counter-clockwise positive; units of x times y). A rolling loop's net roll
    is about proportional to it; a back-and-forth path encloses none."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    return float(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _arrows(ax: Any, x: np.ndarray, y: np.ndarray, n: int = 10, color: str = "C0") -> None:
    """Arrow heads along the polyline (x, y), ``n`` of them equally spaced in arc length, each
    pointing along the segment it sits on."""
    dx, dy = np.diff(x), np.diff(y)
    seg = np.hypot(dx, dy)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    if total <= 0:
        return
    for f in (np.arange(n) + 0.5) / n:
        # s[k] <= f * total < s[k + 1]: a segment that moves (held set-points have length 0)
        k = min(int(np.searchsorted(s, f * total, side="right")) - 1, len(seg) - 1)
        w = (f * total - s[k]) / seg[k]
        tip = np.array([x[k] + w * dx[k], y[k] + w * dy[k]])
        tail = tip - 1e-3 * total * np.array([dx[k], dy[k]]) / seg[k]
        ax.annotate("", xy=tuple(tip), xytext=tuple(tail),
                    arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.2,
                                "mutation_scale": 14})


def plot_manoeuvre(path: Path, episodes: Sequence[Manoeuvre], title: str) -> Any:
    """Write the manoeuvre PNG (one column per policy); returns the Figure.

    Top: the set-point path in (rotate, squeeze) coordinates (deg, :func:`rotate_squeeze`),
    start (circle) and end (square) marked, arrows for the direction. Bottom: object x (mm)
    and theta (deg) against time (s), the goal dashed.
    """
    n = len(episodes)
    fig = _canvas(4.6 * n + 0.4, 8.2)
    axes = fig.subplots(2, n, squeeze=False)
    for ax in axes[0, 1:]:
        ax.sharex(axes[0, 0])
        ax.sharey(axes[0, 0])
    for ax in axes[1, 1:]:
        ax.sharey(axes[1, 0])
    for c, ep in enumerate(episodes):
        rot, sq = rotate_squeeze(ep.setpoint)
        ax = axes[0, c]
        ax.plot(rot, sq, color="C0", lw=1.2)
        _arrows(ax, rot, sq)
        ax.plot(rot[0], sq[0], "o", color="g", ms=7, label="start")
        ax.plot(rot[-1], sq[-1], "s", color="r", ms=7, label="end")
        ax.set_xlabel("rotate (u1 - u2)/2 (deg)")
        area = signed_area(rot, sq)
        ax.set_title(f"{ep.label}: {describe(ep.outcome)}\nenclosed area {area:.1f} deg^2",
                     fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
        t = np.arange(len(ep.pose)) * ep.dt
        x_mm, th_deg = ep.pose[:, 0] * 1e3, np.degrees(ep.pose[:, 2])
        gx, gth = ep.goal[0] * 1e3, float(np.degrees(ep.goal[1]))
        ax = axes[1, c]
        ax.plot(t, x_mm, color="C0", label="object x (mm)")
        ax.plot(t, th_deg, color="C1", label="object theta (deg)")
        ax.axhline(gx, color="C0", ls="--", lw=1, label=f"x* = {gx:g} mm")
        ax.axhline(gth, color="C1", ls="--", lw=1, label=f"theta* = {gth:g} deg")
        ax.set_xlabel("time (s)")
        ax.set_title(f"final errors: x {abs(x_mm[-1] - gx):.2f} mm, theta "
                     f"{abs(th_deg[-1] - gth):.2f} deg", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    axes[0, 0].set_ylabel("squeeze (u1 + u2)/2 (deg)")
    axes[1, 0].set_ylabel("x (mm), theta (deg)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return fig
