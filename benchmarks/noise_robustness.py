"""Success against the sensor-noise scale: the shipped Pose agents and the loop plan on ``-v1``.

::

    python benchmarks/noise_robustness.py --out noise.md --csv noise.csv --png noise.png
    python benchmarks/noise_robustness.py --rows loop-plan --scales 0 1 --n-episodes 2

Each row is played through ``agents.evaluate`` (its ``main``: its model loading, success rule
and records) on the ``-v1`` id of its task, on the validation goals ``reset(seed=SEED + k)``,
k < ``--n-episodes`` (default ``--seed 5000``; the test seeds 10000 + k are refused), at
each point of the sensing axis:

* ``ideal``: ``sensor_model="ideal"`` (exact read-outs, ``rand_sensors`` off), the rest of
  the ``-v1`` semantics (physical checks, the ``Random`` ids' ``obs_noise``) kept: the
  reference point;
* a scale s (``--scales``, default 0 0.5 1 2 4): ``sensor_noise_scale=s``, the realistic
  sensor model (``configs/sensors/realistic.yaml``) with its encoder, torque and tactile
  noise and its torque offset multiplied by s; s = 0 keeps the encoders' quantisation (and
  the encoder-differenced velocities) and, with ``rand_sensors``, the torque gains; s = 1 is
  the ``-v1`` id itself.

The ``-v0`` models were trained on ``-v0`` (ideal sensing): they are played with
``--allow-off-signature`` (``benchmark: false``; ``env_id`` and, except at ``ideal``,
``sensor_model`` differ). The loop plan reads only the goal of the observation, so its row
is the same at every point (a check of the axis, not a measurement of robustness).

Writes the Markdown table to stdout (and ``--out``), one CSV line per (row, point)
(``--csv``: success count, rate and Wilson 95 % interval, the missed episodes' ends) and
the figure (``--png``: success with its interval against the scale, the ideal point at the
left). This script lives outside the package (which never imports the agents); the
evaluations' ``results.yml`` files go under ``--results`` (default a temporary directory).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import math
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / "benchmarks"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

from v0_v1_table import misses_of  # noqa: E402  (one reading of the misses for both tables)

#: The first test seed (docs/results.md): these goals are never played here.
TEST_SEED = 10_000


@dataclass(frozen=True)
class Row:
    """One curve: its ``label``, what ``agents.evaluate`` is given (``kind`` ``"model"`` or
    ``"policy"`` and its ``value``) and the ``-v1`` ``env_id`` it is played on."""

    label: str
    kind: str
    value: str
    env_id: str

    def argv(self) -> list[str]:
        """``agents.evaluate`` arguments of this row (point, goals and output added by
        :func:`evaluate_point`)."""
        args = [f"--{self.kind}", self.value, "--env", self.env_id]
        if self.kind == "model":
            args.append("--allow-off-signature")
        return args


#: Row name -> row.
ROWS: dict[str, Row] = {
    "pose": Row("Pose, teacher-student (v0 model)", "model", "SoftHandPose-v0",
                "SoftHandPose-v1"),
    "pose-v1": Row("Pose, teacher-student, fingertips (v1 model)", "model", "SoftHandPose-v1",
                   "SoftHandPose-v1"),
    "pose-v1-proprio": Row("Pose, teacher-student, joints only (v1 model)", "model",
                           "SoftHandPose-v1_proprio", "SoftHandPose-v1"),
    "pose-random": Row("PoseRandom, teacher-student, fingertips (v0 model)", "model",
                       "SoftHandPoseRandom-v0", "SoftHandPoseRandom-v1"),
    "pose-random-v1": Row("PoseRandom, teacher-student, fingertips (v1 model)", "model",
                          "SoftHandPoseRandom-v1", "SoftHandPoseRandom-v1"),
    "pose-random-v1-proprio": Row("PoseRandom, joints only, the grasp onset and an 80 ms "
                                  "set-point ramp (v1 model)", "model",
                                  "SoftHandPoseRandom-v1_proprio_ramp",
                                  "SoftHandPoseRandom-v1"),
    "loop-plan": Row("Pose, loop plan (scripted)", "policy", "loop-plan", "SoftHandPose-v1"),
}

#: The sensing point without the sensor model.
IDEAL = "ideal"

#: Default scales of the realistic model's noise (dimensionless).
SCALES = (0.0, 0.5, 1.0, 2.0, 4.0)


def point_kwargs(point: str | float) -> list[str]:
    """``--task-kwargs`` of a point: :data:`IDEAL` or a noise scale (>= 0)."""
    if point == IDEAL:
        return ["sensor_model:ideal", "rand_sensors:false"]
    return [f"sensor_noise_scale:{float(point):g}"]


@dataclass(frozen=True)
class Outcome:
    """One evaluation: ``n`` goals, ``successes``, the Wilson 95 % interval ``ci``
    (fractions), the missed episodes' ends ``misses`` (reason -> count) and the wall time
    ``seconds``."""

    n: int
    successes: int
    ci: tuple[float, float]
    misses: dict[str, int]
    seconds: float


def evaluate_point(row: Row, point: str | float, n_episodes: int, seed: int,
                   results: Path) -> Outcome:
    """Play ``row`` at ``point`` through ``agents.evaluate`` (its printed table suppressed;
    ``results.yml`` in ``results/<row value>/<point>``) and read the outcome."""
    import yaml

    from agents.common.metrics import success_count, wilson_interval
    from agents.evaluate import main as evaluate_main

    out = results / row.value / (IDEAL if point == IDEAL else f"scale{float(point):g}")
    argv = [*row.argv(), "--task-kwargs", *point_kwargs(point), "--n-episodes",
            str(n_episodes), "--seed", str(seed), "--no-plots", "--out", str(out), "--force"]
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        summary = evaluate_main(argv)
    seconds = time.perf_counter() - start
    with (out / "results.yml").open() as fh:
        record = yaml.safe_load(fh)
    k = success_count(summary["success_rate"], n_episodes)
    return Outcome(n_episodes, k, wilson_interval(k, n_episodes),
                   misses_of(record["episodes"]), seconds)


def point_name(point: str | float) -> str:
    """``"ideal"`` or ``"0.5x"``."""
    return IDEAL if point == IDEAL else f"{float(point):g}x"


def format_table(points: Sequence[str | float],
                 outcomes: dict[tuple[str, str | float], Outcome]) -> str:
    """Markdown table: one line per row, one column per point, cells
    ``"86 % (43/50; 73.8-93.0 %)"``."""
    rows = list(dict.fromkeys(name for name, _ in outcomes))
    header = "| policy (`--model` / `--policy`) | env | " + " | ".join(
        point_name(p) for p in points) + " |"
    lines = [header, "|" + " --- |" * (len(points) + 2)]
    for name in rows:
        row = ROWS[name]
        cells = []
        for p in points:
            o = outcomes[(name, p)]
            cells.append(f"{100 * o.successes / o.n:.0f} % ({o.successes}/{o.n}; "
                         f"{100 * o.ci[0]:.1f}-{100 * o.ci[1]:.1f} %)")
        lines.append(f"| {row.label} (`{row.value}`) | `{row.env_id}` | "
                     + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_csv(path: Path, outcomes: dict[tuple[str, str | float], Outcome]) -> None:
    """One line per (row, point): row, env, point, scale (empty for ideal), n, successes,
    rate, Wilson low and high (fractions), the misses (``"slip 3; tension 1"``) and the
    wall time (s)."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["row", "env_id", "point", "sensor_noise_scale", "n", "successes",
                    "success_rate", "wilson_low", "wilson_high", "misses", "seconds"])
        for (name, p), o in outcomes.items():
            w.writerow([name, ROWS[name].env_id, point_name(p),
                        "" if p == IDEAL else f"{float(p):g}", o.n, o.successes,
                        f"{o.successes / o.n:.4f}", f"{o.ci[0]:.4f}", f"{o.ci[1]:.4f}",
                        "; ".join(f"{k} {v}" for k, v in o.misses.items()),
                        f"{o.seconds:.1f}"])


def plot(path: Path, points: Sequence[str | float],
         outcomes: dict[tuple[str, str | float], Outcome]) -> None:
    """Success (%) with its Wilson 95 % interval against the noise-scale point, one curve
    per row; the points are evenly spaced (ideal, a square not joined to the curve, then the
    scales in the given order)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(dict.fromkeys(name for name, _ in outcomes))
    fig, ax = plt.subplots(figsize=(6.0, 4.2), dpi=100)
    xs = list(range(len(points)))
    for j, name in enumerate(rows):
        os_ = [outcomes[(name, p)] for p in points]
        rate = [100 * o.successes / o.n for o in os_]
        low = [r - 100 * o.ci[0] for r, o in zip(rate, os_, strict=True)]
        high = [100 * o.ci[1] - r for r, o in zip(rate, os_, strict=True)]
        shift = 0.06 * (j - (len(rows) - 1) / 2)
        # the ideal point is a reference, not a scale: drawn unconnected
        cut = 1 if points and points[0] == IDEAL else 0
        bar = ax.errorbar([x + shift for x in xs[cut:]], rate[cut:],
                          yerr=[low[cut:], high[cut:]], marker="o", capsize=3,
                          label=f"{ROWS[name].label} on {ROWS[name].env_id}")
        if cut:
            ax.errorbar([xs[0] + shift], rate[:1], yerr=[low[:1], high[:1]], marker="s",
                        capsize=3, linestyle="none", color=bar.lines[0].get_color())
    ax.set_xticks(xs, [point_name(p) for p in points])
    ax.set_xlabel("sensing: ideal, or the realistic sensor model's noise x scale")
    ax.set_ylabel("success (%), Wilson 95 % CI")
    n = {o.n for o in outcomes.values()}
    ax.set_title(f"{'/'.join(map(str, sorted(n)))} validation goals per point", fontsize=10)
    ax.set_ylim(-3, 103)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=1)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; prints the table (and writes ``--out``, ``--csv``,
    ``--png``)."""
    from softhand_env.cli import ArgumentParser, check_output_file

    ap: argparse.ArgumentParser = ArgumentParser(prog="python benchmarks/noise_robustness.py",
                                                 description=__doc__.splitlines()[0])
    ap.add_argument("--rows", nargs="+", choices=list(ROWS), default=list(ROWS),
                    metavar="ROW", help="rows to play (default all): " + ", ".join(ROWS))
    ap.add_argument("--scales", nargs="+", type=float, default=list(SCALES),
                    help="sensor_noise_scale values, each in [0, 10] (default 0 0.5 1 2 4)")
    ap.add_argument("--no-ideal", action="store_true", help="skip the ideal-sensing point")
    ap.add_argument("--n-episodes", type=int, default=50,
                    help="goals per row and point, 1 .. 5000 (default 50)")
    ap.add_argument("--seed", type=int, default=5000,
                    help="episode k: reset(seed=SEED + k) (default 5000, the validation goals; "
                         "SEED + n_episodes must stay below the test seeds 10000)")
    ap.add_argument("--results", default=None,
                    help="directory of the evaluations' results.yml (default: a temporary one)")
    ap.add_argument("--out", default=None, help="also write the table to this Markdown file")
    ap.add_argument("--csv", default=None, help="write the CSV to this file")
    ap.add_argument("--png", default=None, help="write the figure to this PNG file")
    ap.add_argument("--force", action="store_true", help="overwrite --out, --csv, --png")
    args = ap.parse_args(argv)
    if not 1 <= args.n_episodes <= 5000:
        ap.error(f"--n-episodes must be in [1, 5000] (got {args.n_episodes})")
    if not 0 <= args.seed <= TEST_SEED - args.n_episodes:
        ap.error(f"--seed must be in [0, {TEST_SEED} - n_episodes]: the goals stay below the "
                 f"test seeds (got {args.seed})")
    for s in args.scales:
        if not (math.isfinite(s) and 0.0 <= s <= 10.0):
            ap.error(f"--scales must be numbers in [0, 10] (got {s:g})")
    for f in (args.out, args.csv, args.png):
        if f is not None:
            check_output_file(f, args.force)
    points: list[str | float] = ([] if args.no_ideal else [IDEAL]) + list(
        dict.fromkeys(args.scales))
    outcomes: dict[tuple[str, str | float], Outcome] = {}
    with contextlib.ExitStack() as stack:
        results = (Path(args.results) if args.results is not None
                   else Path(stack.enter_context(tempfile.TemporaryDirectory())))
        for name in args.rows:
            for p in points:
                o = evaluate_point(ROWS[name], p, args.n_episodes, args.seed, results)
                outcomes[(name, p)] = o
                print(f"{name} {point_name(p)}: {o.successes}/{o.n} ({o.seconds:.0f} s)",
                      file=sys.stderr, flush=True)
    table = format_table(points, outcomes)
    print(table)
    if args.out is not None:
        Path(args.out).write_text(table + "\n")
    if args.csv is not None:
        write_csv(Path(args.csv), outcomes)
    if args.png is not None:
        plot(Path(args.png), points, outcomes)
    return 0


if __name__ == "__main__":
    from softhand_env.cli import run_cli

    raise SystemExit(run_cli(main))
