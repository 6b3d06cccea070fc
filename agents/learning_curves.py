"""Validation learning curves of training runs, one panel per trainer.

``python -m agents.learning_curves RUN [RUN ...] --out curves.png`` reads, for each run
directory, the validation success rate after each evaluation:

* runs of :mod:`agents.train`: ``evaluations.npz`` (``timesteps`` (E,), ``successes`` (E, n));
* runs of :mod:`agents.distill`: ``dagger_curve.npz`` (``env_steps`` (K,), ``success_rate``
  (K,)).

and draws success (%) against environment steps, the PPO runs in the left panel and the DAgger
runs in the right one (a panel only if it has runs), labelled by run directory name. Nothing
in these files is unpickled (``allow_pickle=False``).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from agents.common.cli import ArgumentParser, UserError, check_output_file, run_cli


def read_curve(run: Path) -> tuple[str, np.ndarray, np.ndarray]:
    """(trainer, env steps (K,), validation success rate in [0, 1] (K,)) of a run directory;
    trainer is ``"ppo"`` (evaluations.npz) or ``"dagger"`` (dagger_curve.npz)."""
    dagger, evals = run / "dagger_curve.npz", run / "evaluations.npz"
    try:
        if dagger.is_file():
            with np.load(dagger, allow_pickle=False) as d:
                return "dagger", d["env_steps"].astype(float), d["success_rate"].astype(float)
        if evals.is_file():
            with np.load(evals, allow_pickle=False) as d:
                if "successes" not in d.files or d["successes"].size == 0:
                    raise UserError(f"{evals}: no validation successes recorded")
                return "ppo", d["timesteps"].astype(float), d["successes"].mean(axis=1)
    except (ValueError, KeyError, OSError) as exc:
        raise UserError(f"cannot read the curve of {run}: {exc}") from None
    raise UserError(f"{run}: neither dagger_curve.npz nor evaluations.npz (not a run directory "
                    "with validation)")


def plot_curves(curves: Sequence[tuple[str, str, np.ndarray, np.ndarray]], out: Path,
                title: str = "") -> None:
    """Draw ``(name, trainer, steps, success)`` curves to ``out`` (PNG)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    trainers = [t for t in ("ppo", "dagger") if any(c[1] == t for c in curves)]
    fig = Figure(figsize=(5.0 * len(trainers), 3.6), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(trainers), squeeze=False)[0]
    headings = {"ppo": "PPO (validation goals)", "dagger": "DAgger student (validation goals)"}
    for ax, trainer in zip(axes, trainers, strict=True):
        for name, t, steps, success in curves:
            if t == trainer:
                ax.plot(steps / 1e6, 100 * success, marker="o", ms=3, label=name)
        ax.set_xlabel("environment steps (millions)")
        ax.set_ylabel("success (%)")
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
        ax.set_title(headings[trainer])
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.savefig(out, dpi=110)


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = ArgumentParser(prog="python -m agents.learning_curves", description=__doc__.split("\n")[0])
    p.add_argument("runs", nargs="+", help="run directories")
    p.add_argument("--out", required=True, help="PNG file to write")
    p.add_argument("--title", default="")
    p.add_argument("--force", action="store_true", help="overwrite --out")
    args = p.parse_args(argv)
    out = Path(args.out)
    if out.suffix.lower() != ".png":
        raise UserError(f"--out must name a .png file (got {out})")
    check_output_file(out, args.force)
    return args


def main(argv: Sequence[str] | None = None) -> Path:
    """CLI entry point; returns the written PNG."""
    args = parse_args(argv)
    curves = [(Path(r).name, *read_curve(Path(r))) for r in args.runs]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    plot_curves(curves, out, args.title)
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    run_cli(main)
