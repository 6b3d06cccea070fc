"""Figure command ``contact``: model curves of Figs 2.6, 2.7, 2.11 and 3.3.

``python -m softhand_env.figures contact --out DIR`` writes four PNGs to ``DIR`` (created):

* ``fig2_6_stiffness.png`` -- K of Eq 2.3 (numerical) vs Eq 2.7 (closed form) over d for
  four theta_p, E = 0.2032 MPa. K does not depend on theta_p, so the four series coincide;
  their markers are staggered in d and a second panel shows each series' relative
  difference from the closed form (round-off);
* ``fig2_7_force_energy.png`` -- F (Eq 2.8 vs 2.11) and P (Eq 2.12 vs 2.14);
* ``fig2_11_force_vs_angle.png`` -- F over theta_p for d = 1..8 mm: local minimum at 0;
* ``fig3_3_nonlinear_force.png`` -- theta_p = 0, E = 0.232 MPa: linear Eq 2.11, Eq 3.5 as
  printed (tangent modulus) and in the secant form, Hertz (Eq 3.1) with R = a = 20 mm.

Only the model curves are drawn: the dissertation's experimental curves are not available as
data.  Axes use mm, deg, N (K in N/mm, P in N mm = mJ); the models are evaluated in SI.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from softhand_env.physics import contact

NO_DATA_NOTE = "Model curves only: the paper's experimental curves are not available as data."
MM, DEG = 1e-3, np.pi / 180
A = contact.FINGERTIP_RADIUS
ANGLES_DEG = (0.0, 10.0, 20.0, 30.0)
MARKERS = ("o", "s", "^", "D")


#: The files :func:`run` writes into ``--out``.
OUTPUTS = ("fig2_6_stiffness.png", "fig2_7_force_energy.png", "fig2_11_force_vs_angle.png",
           "fig3_3_nonlinear_force.png")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the ``contact`` subcommand."""
    parser.add_argument("--dpi", type=int, default=150, help="PNG resolution (default 150)")


def run(args: argparse.Namespace) -> list[Path]:
    """Draw the four figures into ``args.out`` (created); return the written paths."""
    dpi = getattr(args, "dpi", 150)
    if dpi <= 0:
        raise ValueError(f"dpi must be > 0 (got {dpi})")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    drawers = {
        "fig2_6_stiffness.png": _fig_2_6,
        "fig2_7_force_energy.png": _fig_2_7,
        "fig2_11_force_vs_angle.png": _fig_2_11,
        "fig3_3_nonlinear_force.png": _fig_3_3,
    }
    written = []
    for name, draw in drawers.items():
        fig = _new_figure(ncols=2 if draw in (_fig_2_6, _fig_2_7) else 1)
        draw(fig)
        fig.text(0.5, 0.01, NO_DATA_NOTE, ha="center", va="bottom", fontsize=8, style="italic")
        fig.tight_layout(rect=(0, 0.04, 1, 1))
        path = out / name
        fig.savefig(path, dpi=dpi)
        written.append(path)
    return written


def _new_figure(ncols: int):
    """A pyplot-free Agg figure with ``ncols`` axes side by side."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.5 * ncols, 4.3))
    FigureCanvasAgg(fig)
    fig.subplots(1, ncols)
    return fig


def _numeric_vs_closed(ax, numeric, closed, scale: float, ylabel: str) -> None:
    """Closed form as lines, numerical integral as markers, one colour per theta_p."""
    d_line = np.linspace(0.0, 8.0, 161) * MM
    d_mark = np.linspace(0.5, 8.0, 16) * MM
    for k, deg in enumerate(ANGLES_DEG):
        colour = f"C{k}"
        ax.plot(d_line / MM, closed(d_line, deg * DEG) * scale, color=colour, lw=1.2)
        ax.plot(
            d_mark / MM,
            numeric(d_mark, deg * DEG) * scale,
            MARKERS[k],
            mfc="none",
            color=colour,
            label=f"θp = {deg:g}°",
        )
    ax.plot([], [], color="k", lw=1.2, label="closed form (line)")
    ax.plot([], [], "o", mfc="none", color="k", label="numerical (markers)")
    ax.set_xlabel("maximum displacement d [mm]")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def _fig_2_6(fig) -> None:
    """K over d for four theta_p. K = 2 pi E d does not depend on theta_p, so the four
    closed-form lines are one line and the numerical values sit on it: the markers of each
    theta_p are drawn at staggered d so that all four series show, and the right panel plots
    each series' relative difference from the closed form (round-off: a few 1e-15)."""
    E = contact.E_CH2
    ax_k, ax_err = fig.axes
    d_line = np.linspace(0.0, 8.0, 161) * MM
    ax_k.plot(d_line / MM, contact.stiffness(d_line, E) * 1e-3, color="k", lw=1.2,
              label=r"Eq 2.7 closed form, $K = 2\pi E d$ (every $\theta_p$)")
    stagger = 0.5 / len(ANGLES_DEG)
    d_err = np.linspace(0.5, 8.0, 31) * MM
    for k, deg in enumerate(ANGLES_DEG):
        colour, marker = f"C{k}", MARKERS[k]
        d_mark = (np.arange(0.5, 8.0, 0.5) + k * stagger) * MM
        label = rf"Eq 2.3 numerical, $\theta_p = {deg:g}^\circ$"
        ax_k.plot(d_mark / MM, contact.stiffness_numeric(d_mark, deg * DEG, E, A) * 1e-3,
                  marker, mfc="none", color=colour, label=label)
        closed = contact.stiffness(d_err, E)
        rel = (contact.stiffness_numeric(d_err, deg * DEG, E, A) - closed) / closed
        ax_err.plot(d_err / MM, rel / 1e-15, marker, ls=("-", "--", "-.", ":")[k], ms=4,
                    mfc="none", color=colour, lw=1.0, label=rf"$\theta_p = {deg:g}^\circ$")
    ax_k.set_xlabel("maximum displacement d [mm]")
    ax_k.set_ylabel("stiffness K [N/mm]")
    ax_k.grid(alpha=0.3)
    ax_k.legend(fontsize=8)
    ax_k.set_title(
        "Fig 2.6: K over d, E = 0.2032 MPa, a = 20 mm\n"
        r"the $\theta_p$ series coincide ($K$ does not depend on $\theta_p$); markers staggered",
        fontsize=9,
    )
    ax_err.axhline(0.0, color="0.5", lw=0.8)
    ax_err.set_xlabel("maximum displacement d [mm]")
    ax_err.set_ylabel(r"(numerical $-$ closed) / closed  [$10^{-15}$]")
    ax_err.grid(alpha=0.3)
    ax_err.legend(fontsize=8)
    ax_err.set_title("relative difference of each series: round-off only", fontsize=9)


def _fig_2_7(fig) -> None:
    E = contact.E_CH2
    ax_f, ax_p = fig.axes
    _numeric_vs_closed(
        ax_f,
        lambda d, th: contact.normal_force_numeric(d, th, E, A),
        lambda d, th: contact.normal_force(d, th, E),
        1.0,
        "elastic force F [N]",
    )
    ax_f.set_title("Fig 2.7: F, Eq 2.8 (numerical) vs Eq 2.11", fontsize=9)
    _numeric_vs_closed(
        ax_p,
        lambda d, th: contact.potential_energy_numeric(d, th, E, A),
        lambda d, th: contact.potential_energy(d, th, E),
        1e3,
        "potential energy P [N mm]",
    )
    ax_p.set_title("Fig 2.7: P, Eq 2.12 (numerical) vs Eq 2.14", fontsize=9)


def _fig_2_11(fig) -> None:
    E = contact.E_CH2
    (ax,) = fig.axes
    theta_line = np.linspace(-30.0, 30.0, 241) * DEG
    theta_mark = np.linspace(-30.0, 30.0, 13) * DEG
    for k, d_mm in enumerate(range(1, 9)):
        d = d_mm * MM
        colour = f"C{k}"
        ax.plot(theta_line / DEG, contact.normal_force(d, theta_line, E), color=colour, lw=1.2)
        numeric = contact.normal_force_numeric(d, theta_mark, E, A)
        ax.plot(theta_mark / DEG, numeric, "o", ms=3, mfc="none", color=colour)
        ax.annotate(f"{d_mm} mm", (30.0, float(contact.normal_force(d, 30 * DEG, E))), fontsize=7)
    ax.set_xlabel("object orientation θp [deg]")
    ax.set_ylabel("elastic force F [N]")
    ax.set_xlim(-32, 36)
    ax.grid(alpha=0.3)
    ax.set_title(
        "Fig 2.11: local minimum of F at θp = 0 for d = 1..8 mm\n"
        "Eq 2.11 (lines), Eq 2.8 numerical (markers); E = 0.2032 MPa, a = 20 mm",
        fontsize=9,
    )


def _fig_3_3(fig) -> None:
    E = contact.E_CH3
    (ax,) = fig.axes
    d = np.linspace(0.0, 10.0, 201) * MM
    linear = contact.normal_force(d, 0.0, E)
    printed = contact.nonlinear_normal_force(d, 0.0, A, "printed")
    curves = (
        (linear, "linear, Eq 2.11", "-"),
        (printed, "Eq 3.5 as printed: E(ε)·ε", "--"),
        (
            contact.nonlinear_normal_force(d, 0.0, A, "secant"),
            "Eq 3.5 secant: σ(ε) (default)",
            "-.",
        ),
        (contact.hertz_force(d, A, E), "Hertz, Eq 3.1 (R = 20 mm, ν = 0.5)", ":"),
    )
    for values, label, style in curves:
        ax.plot(d / MM, values, style, lw=1.5, label=label)
    crossing = _first_crossing(d, printed - linear)
    if crossing is not None:
        f_cross = float(contact.normal_force(crossing, 0.0, E))
        ax.plot(crossing / MM, f_cross, "ko", ms=4)
        ax.annotate(
            f"printed = linear at d = {crossing / MM:.2f} mm",
            (crossing / MM, f_cross),
            xytext=(-150, 25),
            textcoords="offset points",
            fontsize=8,
            arrowprops=dict(arrowstyle="->", lw=0.6),
        )
    ax.set_xlabel("maximum displacement d [mm]")
    ax.set_ylabel("elastic force F [N]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Fig 3.3: force models at θp = 0, E = 0.232 MPa, a = 20 mm", fontsize=9)


def _first_crossing(d: np.ndarray, gap: np.ndarray) -> float | None:
    """First sign change of ``gap`` on the grid ``d``, refined by linear interpolation."""
    changes = np.flatnonzero(np.diff(np.sign(gap[1:]))) + 1  # skip d = 0 (both zero)
    if changes.size == 0:
        return None
    i = int(changes[0])
    return float(d[i] - gap[i] * (d[i + 1] - d[i]) / (gap[i + 1] - gap[i]))
