"""``python -m softhand_env.figures dynamics``: motions 1-8 of §5.5.1 (Figs 5.5 and 5.6).

Runs the chapter-5 model from the parallel point-contact state through the eight set-point
pairs of §5.5.1 (each held ``--duration`` seconds; the paper gives no duration) and writes

* ``fig5_5_motion.png``: finger angles with their set-points, x_obj, y_obj, theta_obj and the
  fingertip deformations d_n, d_t versus time (Fig 5.5),
* ``fig5_6_constraints.png``: |C^H_i| (m) and |C^N_i| (m/s) on log axes (Fig 5.6), values
  below the round-off level :data:`ROUNDOFF_FLOOR` drawn on it, the paper's levels dashed,
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

#: Round-off level of the residuals (m and m/s): double-precision epsilon times the hand's size
#: (~0.1 m) is ~2e-17, and at rest the residuals alternate between that and exactly 0. Values
#: below this floor are drawn on it, so the plot shows a line there, not a solid band.
ROUNDOFF_FLOOR = 1e-16
#: Levels the dissertation's Fig 5.6 reports away from the switching instants (m, m/s).
PAPER_LEVEL_CH, PAPER_LEVEL_CN = 1e-8, 1e-6


#: The files :func:`run` writes into ``--out``.
OUTPUTS = ("trajectory.csv", "fig5_5_motion.png", "fig5_6_constraints.png")


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


def constraint_figure(t: np.ndarray, res: np.ndarray, alpha: float, beta: float):
    """Fig 5.6: the residuals ``res`` (K, 4) of :func:`per_finger_residuals` over ``t`` (K,) s
    under the CSM gains ``alpha``, ``beta`` (1/s, named in the title).

    Log axes; values at or below :data:`ROUNDOFF_FLOOR` are drawn on it (a grey band marks the
    round-off region) and the dissertation's reported levels are dashed. Returns a matplotlib
    ``Figure`` (Agg canvas, not registered with pyplot).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2, sharex=True)
    labels = [r"$|C^H_1|$ (m)", r"$|C^H_2|$ (m)", r"$|C^N_1|$ (m/s)", r"$|C^N_2|$ (m/s)"]
    for k, ax in enumerate(axes.T.flat):
        holonomic = k < 2
        shown = np.maximum(res[:, k], ROUNDOFF_FLOOR)
        ax.semilogy(t, shown, lw=0.9)
        ax.axhspan(ROUNDOFF_FLOOR / 10, ROUNDOFF_FLOOR, color="0.9", zorder=0)
        paper = PAPER_LEVEL_CH if holonomic else PAPER_LEVEL_CN
        ax.axhline(paper, color="C3", ls="--", lw=0.8)
        ax.text(0.01, paper * 1.5, f"paper's level, {paper:.0e}", color="C3", fontsize=7,
                va="bottom", transform=ax.get_yaxis_transform())
        ax.set_ylim(ROUNDOFF_FLOOR / 10, paper * 100)
        ax.set(ylabel=labels[k], title=f"({'abcd'[k]})")
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(
        rf"Fig 5.6 equivalent: constraint residuals under CSM ($\alpha$ = {alpha:.3g} 1/s, "
        rf"$\beta$ = {beta:.3g} 1/s)"
        f"\nvalues at or below the round-off level {ROUNDOFF_FLOOR:.0e} drawn on it (grey band)",
        fontsize=11,
    )
    fig.tight_layout()
    return fig


def run(args: argparse.Namespace) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from softhand_env.physics.motions import run_paper_motions

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
    fig = constraint_figure(t[1:], res[1:], params.alpha, params.beta)
    path = out / "fig5_6_constraints.png"
    fig.savefig(path, dpi=110)
    written.append(path)
    return written
