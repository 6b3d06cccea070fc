"""Figs 4.8 and 4.9: the quasi-static LMEE handling process of Sec. 4.3 (simulation side).

``python -m softhand_env.figures quasistatic --out DIR`` runs the handling process for the
paper's five grasp angles (2.4-7.2 deg) with :func:`softhand_env.quasistatic.handling_process`
and writes

* ``fig4_8_quasistatic.png``: one row per grasp angle; left the x-y path of the object centre
  (mm), right theta_obj (deg) against the counter-clockwise finger rotation phi (deg) of
  operations 2-6; increments where a contact passes the fingertip base are marked;
* ``fig4_9_paths.png``: all x-y paths together.

It prints a summary table (x end points after the +20 deg and -40 deg operations, y at the
grasp, return drift, base-violation increments). The dissertation's experimental curves are
only printed as images, not as data, so the figures show the simulation alone.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from softhand_env.physics.params import load_hand_params
from softhand_env.quasistatic import (
    PAPER_GRASP_ANGLES,
    SCHEMES,
    handling_process,
    handling_summary,
    rotation_angle,
)

CAPTION = (
    "Quasi-static LMEE simulation ({scheme} rolling sums, increment {step:g} deg, hand "
    "'{hand}'). The experimental curves of the dissertation are not available as data and are "
    "not shown. x marks: contact beyond the fingertip base (Eq 2.14 over-predicts)."
)


#: The files :func:`run` writes into ``--out``.
OUTPUTS = ("fig4_8_quasistatic.png", "fig4_9_paths.png")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Register the options of the ``quasistatic`` figure command."""
    parser.add_argument("--step-deg", type=float, default=0.1,
                        help="finger-angle increment in deg (default 0.1)")
    parser.add_argument("--grasp-deg", type=float, nargs="+",
                        default=[round(math.degrees(g), 6) for g in PAPER_GRASP_ANGLES],
                        help="grasp angles in deg (default: 2.4 3.6 4.8 6.0 7.2)")
    parser.add_argument("--scheme", choices=tuple(SCHEMES), default="trapezoid",
                        help="rolling history sums (default trapezoid)")
    parser.add_argument("--hand", default="paper_ch4",
                        help="hand config name or YAML path (default paper_ch4, Table 4.1)")
    parser.add_argument("--dpi", type=int, default=120, help="PNG resolution")


def _summary_text(paths) -> str:
    s = handling_summary(paths)
    lines = [
        "grasp  x_after_+20  x_after_-40  y_grasp   drift_xy   drift_th   base-viol.",
        "(deg)  (mm)         (mm)         (mm)      (mm)       (deg)      (increments)",
    ]
    for k in range(len(paths)):
        lines.append(
            f"{math.degrees(s['grasp_angle'][k]):5.2f}  {s['x_after_ccw'][k] * 1e3:11.3f}  "
            f"{s['x_after_cw'][k] * 1e3:11.3f}  {s['y_grasp'][k] * 1e3:8.3f}  "
            f"{s['drift_xy'][k] * 1e3:9.2e}  {math.degrees(s['drift_theta'][k]):9.2e}  "
            f"{int(s['n_base_violation'][k]):5d} / {len(paths[k])}"
        )
    spread_ccw = np.ptp(s["x_after_ccw"]) * 1e3
    spread_cw = np.ptp(s["x_after_cw"]) * 1e3
    lines.append(
        f"spread of x end points across grasp angles: {spread_ccw:.3f} mm (+20 deg), "
        f"{spread_cw:.3f} mm (-40 deg); paper (experiment): about +-28 mm"
    )
    lines.append(
        f"max constraint residual {np.max(s['max_constraint_residual']):.2e} m, "
        f"max KKT residual {np.max(s['max_kkt_residual']):.2e}, "
        f"base-violation increments in total {int(np.sum(s['n_base_violation']))}"
    )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> list[Path]:
    """Simulate the handling process and write the PNGs; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not (math.isfinite(args.step_deg) and 0 < args.step_deg <= 1.0):
        raise ValueError(f"--step-deg must be in (0, 1] (got {args.step_deg})")
    if any(not (math.isfinite(g) and 0 < g < 30) for g in args.grasp_deg):
        raise ValueError(f"--grasp-deg values must be in (0, 30) deg (got {args.grasp_deg})")
    params = load_hand_params(args.hand)
    step = math.radians(args.step_deg)
    paths = [
        handling_process(math.radians(g), params, step, scheme=args.scheme)
        for g in args.grasp_deg
    ]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    caption = CAPTION.format(scheme=args.scheme, step=args.step_deg, hand=args.hand)
    written = []

    n = len(paths)
    fig, axes = plt.subplots(n, 2, figsize=(9, 2.4 * n + 0.8), squeeze=False)
    for row, pth in enumerate(paths):
        g_deg = math.degrees(pth.grasp_angle)
        ax = axes[row, 0]
        ax.plot(pth.x * 1e3, pth.y * 1e3, lw=1.0, color="C0")
        i1 = pth.end_of(1)
        ax.plot(pth.x[i1] * 1e3, pth.y[i1] * 1e3, "o", ms=4, color="C1", label="grasp")
        bv = pth.base_violation.any(axis=1)
        if bv.any():
            ax.plot(pth.x[bv] * 1e3, pth.y[bv] * 1e3, "x", ms=3, color="C3",
                    label="beyond base")
        ax.set_ylabel(r"$y_{obj}$ (mm)")
        ax.set_title(f"grasp {g_deg:.1f} deg: object path", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower center")
        ax = axes[row, 1]
        m = (pth.op >= 2) & (pth.op <= 6)
        phi = np.degrees(rotation_angle(pth))[m]
        ax.plot(phi, np.degrees(pth.theta_obj[m]), lw=1.0, color="C0")
        if (bv & m).any():
            ax.plot(np.degrees(rotation_angle(pth))[bv & m], np.degrees(pth.theta_obj[bv & m]),
                    "x", ms=3, color="C3")
        ax.set_ylabel(r"$\theta_{obj}$ (deg)")
        ax.set_title(f"grasp {g_deg:.1f} deg: orientation", fontsize=9)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel(r"$x_{obj}$ (mm)")
    axes[-1, 1].set_xlabel(r"finger rotation $\varphi$ (deg): "
                           r"$(\theta_1, \theta_2) = (g + \varphi, g - \varphi)$")
    fig.suptitle("Fig 4.8 (simulation): handling process of Sec. 4.3", fontsize=11)
    fig.text(0.5, 0.005, caption, ha="center", va="bottom", fontsize=7, wrap=True)
    fig.tight_layout(rect=(0, 0.04, 1, 0.98))
    path = out / "fig4_8_quasistatic.png"
    fig.savefig(path, dpi=args.dpi)
    plt.close(fig)
    written.append(path)

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, pth in enumerate(paths):
        ax.plot(pth.x * 1e3, pth.y * 1e3, lw=1.0, color=f"C{k}",
                label=f"grasp {math.degrees(pth.grasp_angle):.1f} deg")
    for xe in (-28.0, 28.0):
        ax.axvline(xe, color="gray", ls=":", lw=0.8)
    ax.text(28.0, ax.get_ylim()[1], " +-28 mm (paper, experiment)", fontsize=7, va="top",
            ha="right", color="gray")
    ax.set_xlabel(r"$x_{obj}$ (mm)")
    ax.set_ylabel(r"$y_{obj}$ (mm)")
    ax.set_title("Fig 4.9 (simulation): object paths for all grasp angles", fontsize=11)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.text(0.5, 0.005, caption, ha="center", va="bottom", fontsize=7, wrap=True)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    path = out / "fig4_9_paths.png"
    fig.savefig(path, dpi=args.dpi)
    plt.close(fig)
    written.append(path)

    print(_summary_text(paths))
    return written
