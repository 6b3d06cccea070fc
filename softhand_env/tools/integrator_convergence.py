"""Convergence of both integrators on the paper's motions: ``python -m
softhand_env.tools.integrator_convergence [--out docs/images/integrator_convergence.png]``.

Plays motions 1-8 of §5.5.1 (1 s each) in 20 ms control periods with RK4 at several substeps
and ROS2 at several steps, and measures against RK4 at 0.0125 ms the largest error of the
object position (mm) and of the angles theta_obj, theta_1, theta_2 (deg) at the ends of all
400 periods. The observed order between neighbouring steps is log2(e(2h) / e(h)); the figure
shows both curves on log-log axes with those orders.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from softhand_env.physics import HandPhysics
from softhand_env.physics.motions import PAPER_MOTIONS_DEG
from softhand_env.physics.params import HandParams

#: Control period (s) and periods per motion.
PERIOD = 0.02
PER_MOTION = 50
#: Steps (s) of the curves and of the reference.
RK4_STEPS = (1e-4, 5e-5, 2.5e-5)
ROS2_STEPS = (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)
REFERENCE_DT = 1.25e-5


def play(params: HandParams) -> np.ndarray:
    """States (400, 20) at the end of every 20 ms period of motions 1-8."""
    physics = HandPhysics(params, check_stability=False)
    n = round(PERIOD / params.dt)
    out = []
    for u in np.radians(PAPER_MOTIONS_DEG):
        for _ in range(PER_MOTION):
            physics.step(u, n)
            out.append(physics.get_state())
    return np.array(out)


def errors(y: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """Largest object-position error (mm) and angle error (deg) of ``y`` against ``ref``."""
    return (1e3 * float(np.abs(y[:, 0:2] - ref[:, 0:2]).max()),
            math.degrees(float(np.abs(y[:, 2:5] - ref[:, 2:5]).max())))


def orders(steps: tuple[float, ...], errs: list[float]) -> list[float]:
    """Observed orders log(e_k / e_{k+1}) / log(h_k / h_{k+1}) between neighbouring steps."""
    return [math.log(errs[k] / errs[k + 1]) / math.log(steps[k] / steps[k + 1])
            for k in range(len(steps) - 1)]


def measure() -> dict[str, list[tuple[float, float, float]]]:
    """(step, position error mm, angle error deg) per step of each integrator."""
    ref = play(HandParams(dt=REFERENCE_DT))
    out: dict[str, list[tuple[float, float, float]]] = {"rk4": [], "ros2": []}
    for h in RK4_STEPS:
        out["rk4"].append((h, *errors(play(HandParams(dt=h)), ref)))
    for h in ROS2_STEPS:
        out["ros2"].append((h, *errors(play(HandParams(integrator="ros2", ros2_dt=h)), ref)))
    return out


def plot(data: dict[str, list[tuple[float, float, float]]], path: str) -> None:
    """Write the log-log figure (two panels: position, angles) to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, col, unit in ((axes[0], 1, "object position error (mm)"),
                          (axes[1], 2, "angle error (deg)")):
        for name, marker in (("rk4", "o"), ("ros2", "s")):
            rows = data[name]
            h = [r[0] * 1e3 for r in rows]
            e = [r[col] for r in rows]
            p = orders(tuple(r[0] for r in rows), e)
            label = f"{name.upper()} (orders {', '.join(f'{x:.2f}' for x in p)})"
            ax.loglog(h, e, marker=marker, label=label)
        ax.axvline(1.0, color="grey", lw=0.8, ls=":")
        ax.set_xlabel("step (ms)")
        ax.set_ylabel(unit)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Motions 1-8 in 20 ms periods, max error over all periods vs RK4 at 0.0125 ms",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=None, help="PNG path of the figure (default: none)")
    args = parser.parse_args(argv)
    data = measure()
    for name, rows in data.items():
        steps = tuple(r[0] for r in rows)
        print(name)
        for h, pos, ang in rows:
            print(f"  step {h * 1e3:8.4f} ms   position {pos:.3e} mm   angles {ang:.3e} deg")
        for label, col in (("position", 1), ("angles", 2)):
            p = orders(steps, [r[col] for r in rows])
            print(f"  orders ({label}):", ", ".join(f"{x:.2f}" for x in p))
    if args.out:
        plot(data, args.out)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
