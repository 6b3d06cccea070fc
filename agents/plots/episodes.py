"""Figures of evaluated episodes: the trajectory plot, its title, the GIF frames.

An *episode record* is a dict with at least ``pose`` (K+1, 3: object x, y, theta in m, m, rad
after the reset and after every step), ``setpoint`` (K+1, 2, rad), ``goal`` (SI, one entry per
target; empty for the goal-free task) and ``success`` (bool), as written by
``agents.evaluate.run_episode``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.play.test_scores import TEST_SEED, VALIDATION_SEED, plays_test_goals
from softhand_env.figures.overlay import annotate_episode

#: Object motion counted as one unit when choosing an episode to animate: 1 mm in x, 1 deg in
#: theta (the success tolerances).
MOTION_UNITS = (1e-3, math.radians(1.0))


def evaluation_title(env_id: str, policy: str, n_episodes: int, seed: int,
                     targets: Sequence[str]) -> str:
    """Title of an evaluation: env, policy and what was played (goals, or goal-free episodes).
    The goals are called test goals when the set meets the test family
    (:func:`agents.play.test_scores.plays_test_goals`), validation goals when it lies within
    the validation seeds (from :data:`~agents.play.test_scores.VALIDATION_SEED` up to the test
    family), else goals."""
    seeds = f"seed {seed}" if n_episodes == 1 else f"seeds {seed}..{seed + n_episodes - 1}"
    if targets:
        if plays_test_goals(seed, n_episodes, None):
            family = "test "
        elif VALIDATION_SEED <= seed and seed + n_episodes <= TEST_SEED:
            family = "validation "
        else:
            family = ""
        goals = f"1 {family}goal" if n_episodes == 1 else f"{n_episodes} {family}goals"
        return f"{env_id}, {policy} policy, {goals} ({seeds})"
    runs = "1 episode" if n_episodes == 1 else f"{n_episodes} episodes"
    return f"{env_id}, {policy} policy, {runs} without a goal ({seeds})"


def object_motion(episode: dict[str, Any]) -> float:
    """Largest displacement of the object from its start pose, in :data:`MOTION_UNITS`."""
    pose = np.asarray(episode["pose"], dtype=np.float64)
    dx = np.abs(pose[:, 0] - pose[0, 0]) / MOTION_UNITS[0]
    dth = np.abs(pose[:, 2] - pose[0, 2]) / MOTION_UNITS[1]
    return float(np.max(np.maximum(dx, dth)))


def choose_episode(episodes: Sequence[dict[str, Any]]) -> int:
    """Index of the episode to animate: the one in which the object moves most, among the
    successful episodes if there are any (a dropped object also moves a lot)."""
    if not episodes:
        raise ValueError("no episodes to choose from")
    candidates = [k for k, ep in enumerate(episodes) if ep.get("success")] or range(len(episodes))
    return max(candidates, key=lambda k: object_motion(episodes[k]))


def plot_episodes(path: Path, episodes: Sequence[dict[str, Any]], targets: Sequence[str],
                  dt: float, title: str, highlight: int = 0, n_max: int = 10):
    """Write a PNG: object x and theta of up to ``n_max`` episodes (goals dashed; episode
    ``highlight`` always among them, bold), and the set-points of episode ``highlight`` over
    time and as a path in finger-angle space (rolling loops show there). ``dt`` is the control
    period (s). Returns the matplotlib ``Figure`` (Agg canvas, not registered with pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not 0 <= highlight < len(episodes):
        raise ValueError(f"highlight must index one of the {len(episodes)} episodes")
    fig = Figure(figsize=(16, 4.2))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 4)
    shown = shown_episodes(len(episodes), highlight, n_max)
    for k, index in enumerate(shown):
        ep = episodes[index]
        t = np.arange(len(ep["pose"])) * dt
        color, lw = f"C{k % 10}", 2.0 if index == highlight else 1.0
        axes[0].plot(t, ep["pose"][:, 0] * 1e3, color=color, lw=lw)
        axes[1].plot(t, np.degrees(ep["pose"][:, 2]), color=color, lw=lw)
        for name, g in zip(targets, ep["goal"], strict=True):
            ax, val = (axes[0], g * 1e3) if name == "x" else (axes[1], math.degrees(g))
            ax.axhline(val, color=color, ls="--", lw=0.8)
    ep = episodes[highlight]
    t = np.arange(len(ep["setpoint"])) * dt
    sp = np.degrees(ep["setpoint"])
    axes[2].plot(t, sp[:, 0], label=r"$\theta_1^d$ (right)")
    axes[2].plot(t, sp[:, 1], label=r"$\theta_2^d$ (left)")
    axes[2].legend(fontsize=8)
    for ax, label in zip(axes, (r"object $x$ (mm)", r"object $\theta$ (deg)",
                                f"set-points, episode {highlight} (deg)"), strict=False):
        ax.set_xlabel("time (s)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[3].plot(sp[:, 0], sp[:, 1], lw=1)
    axes[3].plot(sp[0, 0], sp[0, 1], "go", ms=5, label="start")
    axes[3].plot(sp[-1, 0], sp[-1, 1], "rs", ms=5, label="end")
    axes[3].set_xlabel(r"$\theta_1^d$ (deg)")
    axes[3].set_ylabel(r"$\theta_2^d$ (deg)")
    axes[3].set_title(f"finger-space path, episode {highlight}", fontsize=9)
    axes[3].legend(fontsize=8)
    axes[3].grid(alpha=0.3)
    what = (f"object pose of {describe_indices(shown, len(episodes))}"
            + (f", episode {highlight} bold" if len(shown) > 1 else "")
            + (", goals dashed" if targets else ""))
    fig.suptitle(f"{title}\n{what}", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    return fig


def shown_episodes(n_episodes: int, highlight: int, n_max: int = 10) -> list[int]:
    """Indices of the episodes drawn: the first ``n_max``, the last of them replaced by
    ``highlight`` if it is not among them."""
    shown = list(range(min(n_episodes, n_max)))
    if highlight not in shown:
        shown[-1] = highlight
    return shown


def describe_indices(shown: Sequence[int], n_episodes: int) -> str:
    """``"all 3 episodes"``, ``"episodes 0-8 and 11 of 12"``: what a plot of ``shown`` holds."""
    if list(shown) == list(range(n_episodes)):
        return "the episode" if n_episodes == 1 else f"all {n_episodes} episodes"
    runs: list[str] = []
    start = prev = shown[0]
    for k in [*shown[1:], None]:
        if k is not None and k == prev + 1:
            prev = k
            continue
        runs.append(f"{start}" if start == prev else f"{start}-{prev}")
        if k is not None:
            start = prev = k
    listed = runs[0] if len(runs) == 1 else ", ".join(runs[:-1]) + " and " + runs[-1]
    return f"episodes {listed} of {n_episodes}"


def gif_frames(frames: Sequence[np.ndarray], dt: float, targets: Sequence[str],
               goal: Sequence[float], poses: Sequence[Sequence[float]] | None = None,
               fps: int = 25) -> tuple[list[np.ndarray], float]:
    """Frames of one episode for a GIF at about ``fps`` frames/s of simulated time, each with
    the time, goal and object pose drawn on it (:func:`~softhand_env.figures.overlay.
    annotate_episode`); returns the frames and the GIF frame duration in ms."""
    if fps < 1:
        raise ValueError(f"fps must be >= 1 (got {fps})")
    stride = max(1, round(1.0 / (fps * dt)))
    picked = list(range(0, len(frames), stride))
    shown = [frames[k] for k in picked]
    # annotate_episode stamps frame j with j * dt: pass the stride's time step
    annotated = annotate_episode(shown, stride * dt, targets, goal,
                                 None if poses is None else [poses[k] for k in picked])
    return annotated, 1000.0 * stride * dt
