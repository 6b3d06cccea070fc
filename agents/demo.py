"""The headline demo: reproduce the paper's runs and evaluate the blind agents, writing figures.

::

    python -m agents.demo --out out/demo            # ~2-5 min on 2 cores

1. Chapter 5: motions 1-8 of §5.5.1 through the dynamic model (Figs 5.5/5.6, trajectory CSV)
   and the same sequence replayed through ``gym.make("SoftHand-v0")`` by the scripted agent
   (animation).
2. Chapter 4: the quasi-static handling process (Figs 4.8/4.9).
3. The goal tasks: the model-based blind baseline and the shipped learned agent
   (``agents/models/<algo>/<env id>_1``, installed with the package; a missing one is an error,
   exit code 2, naming the file) on the same seeded held-out goals; a comparison table is
   printed and written to ``summary.md``.

Every input is checked before anything runs: ``--n-episodes`` and ``--seed`` as
``agents.evaluate`` checks them, ``--out`` a writable directory holding no file (an earlier
demo is not overwritten without ``--force``), a shipped model for each goal task.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

from agents.common.cli import (
    SEED_MAX,
    ArgumentParser,
    UserError,
    check_output_dir,
    check_range,
    run_cli,
)
from agents.common.metrics import ERROR_KEYS, summary_success_text
from agents.runs.loading import resolve_model, shipped_models

GOAL_ENVS = ("SoftHandReorient-v0", "SoftHandTranslate-v0", "SoftHandPose-v0")


def learned_label(model: str | Path) -> str:
    """Table label of a model, from its run config (algorithm; residual on the loop plan, or a
    blind student distilled from a privileged teacher)."""
    run = resolve_model(model)
    if run.record.get("trainer") == "dagger":
        return "learned (privileged PPO teacher -> blind student, no plan)"
    wrappers = str(run.hyperparams.get("env_wrapper") or "")
    residual = ", residual on the loop plan" if "ResidualWrapper" in wrappers else ""
    return f"learned ({run.algo.upper()}{residual})"


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command-line arguments, range-checked as ``agents.evaluate`` checks them."""
    p = ArgumentParser(prog="python -m agents.demo", description=__doc__.split("\n")[0])
    p.add_argument("--out", default="out/demo", help="output directory (default out/demo)")
    p.add_argument("--n-episodes", type=int, default=20,
                   help="held-out goals per agent, 1 .. 100000 (default 20; the README "
                        "table uses 100)")
    p.add_argument("--seed", type=int, default=10000, help="first goal seed (default 10000)")
    p.add_argument("--force", action="store_true",
                   help="write into an --out that already holds files (overwriting them)")
    args = p.parse_args(argv)
    check_range("--n-episodes", args.n_episodes, 1, 100_000)
    check_range("--seed", args.seed, 0, SEED_MAX - args.n_episodes)
    return args


def check_inputs(args: argparse.Namespace) -> dict[str, Path]:
    """Everything the demo needs, before any of it runs: ``--out`` a writable directory that
    holds no file (unless ``--force``), a shipped model for every goal task. Returns the
    shipped model of each goal task."""
    check_output_dir(args.out, ("*",), args.force)
    shipped = shipped_models()
    models = {}
    for env_id in GOAL_ENVS:
        if env_id not in shipped:
            raise UserError(f"no shipped model for {env_id}: expected "
                            f"agents/models/<algo>/{env_id}_1/{env_id}.zip (package data)")
        models[env_id] = shipped[env_id]
    return models


def _row(env_id: str, agent: str, s: dict[str, float]) -> str:
    def fmt(name: str, unit: str) -> str:
        key = ERROR_KEYS[name]
        if f"median_{key}" not in s:
            return "-"
        return f"{s[f'median_{key}']:.2f} / {s[f'max_{key}']:.2f} {unit}"

    success = (summary_success_text(s) if "n_episodes" in s
               else f"{100 * s['success_rate']:.0f} %")
    return (f"| {env_id} | {agent} | {success} | "
            f"{fmt('x', 'mm')} | {fmt('theta', 'deg')} |")


def main(argv: Sequence[str] | None = None) -> list[str]:
    """CLI entry point; returns the rows of the comparison table. Every input is checked
    (:func:`check_inputs`) before anything is run or written."""
    from agents import evaluate
    from softhand_env import figures

    args = parse_args(argv)
    models = check_inputs(args)
    out = Path(args.out)
    force = ["--force"] if args.force else []
    t0 = time.perf_counter()
    print("== chapter 5: motions 1-8 (dynamic model)")
    figures.main(["dynamics", "--out", str(out / "chapter5"), *force])
    print("== chapter 5: scripted replay through gym.make('SoftHand-v0')")
    evaluate.main(["--policy", "paper", "--n-episodes", "1", "--out", str(out / "chapter5_gym"),
                   *force])
    print("== chapter 4: quasi-static handling process")
    figures.main(["quasistatic", "--out", str(out / "chapter4"), *force])
    rows = ["| task | agent | success (95 % CI) | final \\|x\\| error (median / max) "
            "| final \\|θ\\| error (median / max) |",
            "| --- | --- | --- | --- | --- |"]
    common = ["--n-episodes", str(args.n_episodes), "--seed", str(args.seed), *force]
    for env_id in GOAL_ENVS:
        print(f"== {env_id}: model-based blind baseline")
        s = evaluate.main(["--policy", "model-based", "--env", env_id, *common, "--no-plots",
                           "--out", str(out / f"{env_id}_baseline")])
        rows.append(_row(env_id, "model-based baseline", s))
        model = models[env_id]
        print(f"== {env_id}: learned agent ({model})")
        s = evaluate.main(["--model", str(model), *common,
                           "--out", str(out / f"{env_id}_learned")])
        rows.append(_row(env_id, learned_label(model), s))
    summary = "\n".join(rows)
    (out / "summary.md").write_text(
        f"Held-out goals: seeds {args.seed} .. {args.seed + args.n_episodes - 1}; success = "
        "within 1 mm / 1 deg at the end of the episode.\n\n" + summary + "\n"
    )
    print(summary)
    print(f"demo written to {out} in {time.perf_counter() - t0:.0f} s")
    return rows


if __name__ == "__main__":
    run_cli(main)
