"""``python -m softhand_env.figures dynamics``: motions 1-8 of §5.5.1 (Figs 5.5 and 5.6).

Runs the chapter-5 model from the parallel point-contact state through the eight set-point
pairs of §5.5.1 (each held ``--duration`` seconds; the paper gives no duration) and writes

* ``fig5_5_motion.png``: finger angles with their set-points, x_obj, y_obj, theta_obj and the
  fingertip deformations d_n, d_t versus time (Fig 5.5),
* ``fig5_6_constraints.png``: |C^H_i| (m) and |C^N_i| (m/s) on log axes (Fig 5.6),
* ``trajectory.csv``: the recorded states (SI units, header names every column).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from softhand_env.physics.model import (
    DN_1,
    DT_1,
    NY,
    TH_1,
    TH_OBJ,
    X_OBJ,
    Y_OBJ,
    constraint_residuals,
    pack_params,
)
from softhand_env.physics.params import load_hand_params


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--duration", type=float, default=1.0, help="seconds per motion (1.0)")
    parser.add_argument("--config", default="paper_ch5", help="hand config name or YAML path")


def per_finger_residuals(y: np.ndarray, prm: np.ndarray) -> np.ndarray:
    """|C^H_1|, |C^H_2| (m), |C^N_1|, |C^N_2| (m/s) of each row of y (K, 20); shape (K, 4)."""
    out = np.empty((len(y), 4))
    buf = np.empty(4)
    for k, row in enumerate(y):
        constraint_residuals(np.ascontiguousarray(row), prm, buf)
        out[k] = np.abs(buf)
    return out


def run(args: argparse.Namespace) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from softhand_env.tools.simulate import run_paper_motions

    if not args.duration > 0:
        raise ValueError(f"--duration must be > 0 (got {args.duration})")
    params = load_hand_params(args.config)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    traj = run_paper_motions(params, duration=args.duration)
    t, y = traj.t, traj.y
    assert y.shape[1] == NY
    written = []

    csv = out / "trajectory.csv"
    traj.to_csv(str(csv))
    written.append(csv)

    fig, axes = plt.subplots(3, 2, figsize=(11, 9), sharex=True)
    for i, ax in enumerate(axes[0]):
        ax.plot(t, np.degrees(y[:, TH_1 + i]), label=rf"$\theta_{i + 1}$")
        ax.plot(t, np.degrees(traj.setpoint[:, i]), "--", label=rf"$\theta_{i + 1}^d$")
        ax.set_ylabel("deg")
        ax.set_title(f"({'ab'[i]}) finger {i + 1} ({'right' if i == 0 else 'left'})")
        ax.legend(loc="best")
    axes[1, 0].plot(t, 1e3 * y[:, X_OBJ])
    axes[1, 0].set(ylabel="mm", title=r"(c) $x_{obj}$")
    axes[1, 1].plot(t, 1e3 * y[:, Y_OBJ])
    axes[1, 1].set(ylabel="mm", title=r"(d) $y_{obj}$")
    axes[2, 0].plot(t, np.degrees(y[:, TH_OBJ]))
    axes[2, 0].set(ylabel="deg", title=r"(e) $\theta_{obj}$", xlabel="time (s)")
    for j, name in enumerate([r"$d_{n1}$", r"$d_{n2}$"]):
        axes[2, 1].plot(t, 1e3 * y[:, DN_1 + j], label=name)
    for j, name in enumerate([r"$d_{t1}$", r"$d_{t2}$"]):
        axes[2, 1].plot(t, 1e3 * y[:, DT_1 + j], ":", label=name)
    axes[2, 1].set(ylabel="mm", title="(f) fingertip deformations", xlabel="time (s)")
    axes[2, 1].legend(loc="best", ncol=2)
    for s in traj.switch_times:
        for ax in axes.flat:
            ax.axvline(s, color="0.85", lw=0.8, zorder=0)
    fig.suptitle(
        f"Fig 5.5 equivalent: motions 1-8 of §5.5.1, {args.duration:g} s each (model output)"
    )
    fig.tight_layout()
    path = out / "fig5_5_motion.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)

    res = per_finger_residuals(y, pack_params(params))
    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
    labels = [r"$|C^H_1|$ (m)", r"$|C^H_2|$ (m)", r"$|C^N_1|$ (m/s)", r"$|C^N_2|$ (m/s)"]
    for k, ax in enumerate(axes.T.flat):
        ax.semilogy(t[1:], np.maximum(res[1:, k], 1e-20))
        ax.set(ylabel=labels[k], title=f"({'abcd'[k]})")
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle("Fig 5.6 equivalent: constraint residuals under CSM (alpha = 2e4, beta = 1e4)")
    fig.tight_layout()
    path = out / "fig5_6_constraints.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)
    return written
