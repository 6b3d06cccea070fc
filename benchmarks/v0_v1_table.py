"""Every shipped ``-v0`` model and scripted baseline on its ``-v0`` id and on the corresponding
``-v1`` id (the models shipped for the ``-v1`` ids are scored on their own id, docs/results.md).

::

    python benchmarks/v0_v1_table.py --seed 10000 --out v0_v1.md        # the docs' table
    python benchmarks/v0_v1_table.py --rows pose loop-plan --n-episodes 10   # validation goals

Each row is played twice through ``agents.evaluate`` (its ``main``, so with exactly its model
loading, keywords, success rule and records): on the ``-v0`` id (the benchmark) and on the
``-v1`` id of the same task, on the same goals ``reset(seed=SEED + k)``, k < ``--n-episodes``.
A shipped model (trained on ``-v0``, ideal sensing) is played on ``-v1`` with
``--allow-off-signature``: the evaluation is labelled ``benchmark: false`` and the differing
signature fields (env id, sensor model) are listed; the scripted baselines have no signature
and are played on ``-v1`` as its benchmark. The paper's chapter-5 motions (``--policy paper``,
one goal-free episode on ``SoftHand-v0`` / ``SoftHand-v1``) close the table as a reference:
no success rate, only how the episode ended and the friction it needed.

Per row and id the table gives the success rate with its Wilson 95 % interval, how the missed
episodes ended (the failure reasons of ``info["termination_reason"]``, counted; ``out of
tolerance``: the episode ran to its time limit without failing and ended off the goal), and
the friction needed (the largest friction ratio |J_t| / J_n of an episode while its grasp held,
the largest over the goals; on ``-v1`` the ratio of the 20 ms windows, on ``-v0`` of the
control steps). ``--seed 10000`` plays the test goals: each is then a test score of the model
(the shipped models are not written to; the docs list the scores, docs/results.md). The
default ``--seed 5000`` plays validation goals.

This script lives outside the package (which never imports the agents); it writes the
evaluations' ``results.yml`` files under ``--results`` (default a temporary directory) and
prints the Markdown table (``--out FILE``: also written there).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@dataclass(frozen=True)
class Row:
    """One line of the table: ``tier`` and ``task`` as docs/results.md names them, the
    ``policy`` as the table shows it, what ``agents.evaluate`` is given (``kind`` ``"model"``
    or ``"policy"`` and its ``value``), and the ``-v0`` id (the ``-v1`` id is the same with
    ``-v1``)."""

    tier: str
    task: str
    policy: str
    kind: str
    value: str
    v0_id: str

    @property
    def v1_id(self) -> str:
        """The ``-v1`` id of the same task."""
        return self.v0_id.removesuffix("-v0") + "-v1"

    def argv(self, env_id: str) -> list[str]:
        """``agents.evaluate`` arguments of this row on ``env_id`` (goal set and output added
        by :func:`evaluate_row`)."""
        args = [f"--{self.kind}", self.value, "--env", env_id]
        if self.kind == "model" and env_id != self.v0_id:
            args.append("--allow-off-signature")
        return args


#: Row name -> row: the shipped models (agents/models) and the scripted baselines of
#: docs/results.md, then the paper's motions.
ROWS: dict[str, Row] = {
    "translate": Row("nominal", "Translate", "PPO", "model", "SoftHandTranslate-v0",
                     "SoftHandTranslate-v0"),
    "reorient": Row("nominal", "Reorient", "PPO", "model", "SoftHandReorient-v0",
                    "SoftHandReorient-v0"),
    "pose": Row("nominal", "Pose", "teacher-student", "model", "SoftHandPose-v0",
                "SoftHandPose-v0"),
    "pose-residual": Row("nominal", "Pose", "residual PPO on the loop plan", "model",
                         "SoftHandPose-v0_residual", "SoftHandPose-v0"),
    "reorient-random": Row("Random", "Reorient", "PPO", "model", "SoftHandReorientRandom-v0",
                           "SoftHandReorientRandom-v0"),
    "pose-random": Row("Random", "Pose", "teacher-student, fingertips", "model",
                       "SoftHandPoseRandom-v0", "SoftHandPoseRandom-v0"),
    "translate-model-based": Row("nominal", "Translate", "model-based", "policy",
                                 "model-based", "SoftHandTranslate-v0"),
    "reorient-model-based": Row("nominal", "Reorient", "model-based", "policy", "model-based",
                                "SoftHandReorient-v0"),
    "pose-model-based": Row("nominal", "Pose", "model-based", "policy", "model-based",
                            "SoftHandPose-v0"),
    "loop-plan": Row("nominal", "Pose", "loop plan", "policy", "loop-plan", "SoftHandPose-v0"),
    "reorient-random-model-based": Row("Random", "Reorient", "model-based", "policy",
                                       "model-based", "SoftHandReorientRandom-v0"),
    "pose-random-model-based": Row("Random", "Pose", "model-based", "policy", "model-based",
                                   "SoftHandPoseRandom-v0"),
    "pose-random-loop-plan": Row("Random", "Pose", "loop plan", "policy", "loop-plan",
                                 "SoftHandPoseRandom-v0"),
    "paper": Row("replay", "chapter-5 motions", "paper", "policy", "paper", "SoftHand-v0"),
}


@dataclass(frozen=True)
class Outcome:
    """One evaluation: ``n`` goals, ``successes``, the Wilson 95 % interval ``ci`` (fractions),
    the missed episodes' ends ``misses`` (reason -> count), ``friction`` (the largest friction
    ratio needed), ``off_signature`` (the fields the model was played off), the wall time
    ``seconds`` and the ``results.yml`` path."""

    n: int
    successes: int
    ci: tuple[float, float]
    misses: dict[str, int]
    friction: float
    off_signature: tuple[str, ...]
    seconds: float
    results: Path


#: How a missed episode that did not fail is named.
OUT_OF_TOLERANCE = "out of tolerance"


def misses_of(episodes: Sequence[dict[str, Any]]) -> dict[str, int]:
    """The ends of the missed episodes (``success`` False) of ``results.yml`` records: the
    failure reason (``termination_reason`` with ``_`` read as a space) or
    :data:`OUT_OF_TOLERANCE`, counted, most frequent first (ties by name)."""
    counts = Counter((ep["termination_reason"] or OUT_OF_TOLERANCE).replace("_", " ")
                     for ep in episodes if not ep["success"])
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def evaluate_row(row: Row, env_id: str, n_episodes: int, seed: int, results: Path) -> Outcome:
    """Play ``row`` on ``env_id`` through ``agents.evaluate`` (its printed table suppressed;
    ``results.yml`` in ``results/<policy value>/<env id>``) and read the outcome."""
    import yaml

    from agents.common.metrics import success_count, wilson_interval
    from agents.evaluate import main as evaluate_main

    out = results / row.value / env_id
    n = 1 if row.value == "paper" else n_episodes
    argv = [*row.argv(env_id), "--n-episodes", str(n), "--seed", str(seed), "--no-plots",
            "--out", str(out), "--force"]
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        summary = evaluate_main(argv)
    seconds = time.perf_counter() - start
    with (out / "results.yml").open() as fh:
        record = yaml.safe_load(fh)
    k = success_count(summary["success_rate"], n)
    return Outcome(n, k, wilson_interval(k, n), misses_of(record["episodes"]),
                   float(summary["max_friction_ratio"]), tuple(record["off_signature"]),
                   seconds, out / "results.yml")


def success_cell(o: Outcome, goal_task: bool) -> str:
    """``"86 % (86/100; 77.9-91.5 %)"``, or ``"no goal"`` for the goal-free replay."""
    if not goal_task:
        return "no goal"
    low, high = o.ci
    return (f"{100 * o.successes / o.n:.0f} % ({o.successes}/{o.n}; "
            f"{100 * low:.1f}-{100 * high:.1f} %)")


def misses_cell(o: Outcome, goal_task: bool) -> str:
    """The missed episodes' ends, ``"slip 3, out of tolerance 2"`` (``"none"``); for the
    goal-free replay how its episode ended."""
    misses = o.misses
    if not goal_task:
        misses = {k: v for k, v in misses.items() if k != OUT_OF_TOLERANCE}
    return ", ".join(f"{k} {v}" for k, v in misses.items()) or "none"


HEADER = ("| tier | task | policy (`--model` / `--policy`) | goals | v0 success (95 % CI) | "
          "v1 success (95 % CI) | v0 misses | v1 misses | friction needed v0 / v1 |")


def format_table(outcomes: Sequence[tuple[Row, Outcome, Outcome]]) -> str:
    """The Markdown table of (row, v0 outcome, v1 outcome) triples."""
    lines = [HEADER, "|" + " --- |" * (HEADER.count("|") - 1)]
    for row, v0, v1 in outcomes:
        goal_task = row.value != "paper"
        lines.append(
            f"| {row.tier} | {row.task} | {row.policy} (`{row.value}`) | {v0.n} | "
            f"{success_cell(v0, goal_task)} | {success_cell(v1, goal_task)} | "
            f"{misses_cell(v0, goal_task)} | {misses_cell(v1, goal_task)} | "
            f"{v0.friction:.3f} / {v1.friction:.3f} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; prints the table (and writes it to ``--out``)."""
    from softhand_env.cli import ArgumentParser, check_output_file

    ap: argparse.ArgumentParser = ArgumentParser(prog="python benchmarks/v0_v1_table.py",
                                                 description=__doc__.splitlines()[0])
    ap.add_argument("--rows", nargs="+", choices=list(ROWS), default=list(ROWS),
                    metavar="ROW", help="rows to play (default all): " + ", ".join(ROWS))
    ap.add_argument("--n-episodes", type=int, default=100,
                    help="goals per row and id, 1 .. 100000 (default 100; the paper row: 1)")
    ap.add_argument("--seed", type=int, default=5000,
                    help="episode k: reset(seed=SEED + k) (default 5000, the validation goals; "
                         "10000: the test goals)")
    ap.add_argument("--results", default=None,
                    help="directory of the evaluations' results.yml (default: a temporary one)")
    ap.add_argument("--out", default=None, help="also write the table to this Markdown file")
    ap.add_argument("--force", action="store_true", help="overwrite --out")
    args = ap.parse_args(argv)
    if not 1 <= args.n_episodes <= 100_000:
        ap.error(f"--n-episodes must be in [1, 100000] (got {args.n_episodes})")
    if not 0 <= args.seed <= 2**32 - 1 - args.n_episodes:
        ap.error(f"--seed must be in [0, 2**32 - 1 - n_episodes] (got {args.seed})")
    if args.out is not None:
        check_output_file(args.out, args.force)
    with contextlib.ExitStack() as stack:
        results = (Path(args.results) if args.results is not None
                   else Path(stack.enter_context(tempfile.TemporaryDirectory())))
        outcomes = []
        for name in args.rows:
            row = ROWS[name]
            v0 = evaluate_row(row, row.v0_id, args.n_episodes, args.seed, results)
            v1 = evaluate_row(row, row.v1_id, args.n_episodes, args.seed, results)
            print(f"{name}: {row.v0_id} {v0.successes}/{v0.n} ({v0.seconds:.0f} s), "
                  f"{row.v1_id} {v1.successes}/{v1.n} ({v1.seconds:.0f} s)"
                  + (f"; off-signature: {'; '.join(v1.off_signature)}"
                     if v1.off_signature else ""), file=sys.stderr, flush=True)
            outcomes.append((row, v0, v1))
    table = format_table(outcomes)
    print(table)
    if args.out is not None:
        Path(args.out).write_text(table + "\n")
    return 0


if __name__ == "__main__":
    from softhand_env.cli import run_cli

    raise SystemExit(run_cli(main))
