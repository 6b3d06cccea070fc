"""The shipped agents with either integrator: success on the same goals, RK4 against ROS2.

::

    python benchmarks/integrator_agents.py --out integrator_agents.md
    python benchmarks/integrator_agents.py --models SoftHandPose-v0 --n-episodes 3 --seed 5000

Each shipped default model (``--models``, default every soft-hand id that has one) is played
through ``agents.evaluate`` (its ``main``: its model loading, success rule and records) on
its own id twice, on the same goals ``reset(seed=SEED + k)``, k < ``--n-episodes``: with the
id's registered integrator and with the other one, set by ``--task-kwargs hand_overrides``
(the id's registered hand overrides, e.g. the ``Random`` ids' ``dt`` of 0.05 ms for RK4,
with ``integrator`` replaced). The ``-v0`` ids run RK4 at their ``dt``, the ``-v1`` ids
ROS2 at 1 ms, so the ``-v0`` models are checked on ROS2 and the ``-v1`` models on RK4,
without retraining. The default goals are the first 100 test goals (seed 10000): the models
are final and nothing is chosen on the result; the evaluation only compares the two
integrators under a fixed policy.

Prints a Markdown table (per model: success with either integrator with the Wilson 95 %
interval, the difference in points, the goals whose outcome differs, median final errors)
and writes it to ``--out``. This script lives outside the package (which never imports the
agents); the evaluations' ``results.yml`` files go under ``--results`` (default a temporary
directory).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: The two integrators (``hand_overrides["integrator"]``).
INTEGRATORS = ("rk4", "ros2")


def shipped_ids() -> list[str]:
    """Soft-hand ids with a shipped default model, in registry order."""
    from agents.runs.loading import shipped_models
    from softhand_env.envs import ENV_IDS

    shipped = shipped_models()
    return [env_id for env_id in ENV_IDS if env_id in shipped]


def hand_overrides(env_id: str, integrator: str) -> dict[str, Any]:
    """The id's registered ``hand_overrides`` with ``integrator`` set."""
    from softhand_env.envs import registered_kwargs

    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {INTEGRATORS} (got {integrator!r})")
    return {**registered_kwargs(env_id).get("hand_overrides", {}), "integrator": integrator}


def registered_integrator(env_id: str) -> str:
    """The integrator ``env_id`` runs by default (``"rk4"`` unless its hand overrides say)."""
    from softhand_env.envs import registered_kwargs

    return str(registered_kwargs(env_id).get("hand_overrides", {}).get("integrator", "rk4"))


def flow_mapping(values: dict[str, Any]) -> str:
    """``values`` (str and float entries) as a YAML flow mapping that reads back the same
    (floats with a decimal point and exponent, which YAML 1.1 reads as floats)."""
    items = []
    for key, v in values.items():
        if isinstance(v, bool) or not isinstance(v, (str, float, int)):
            raise TypeError(f"{key}: only str and number entries (got {v!r})")
        items.append(f"{key}: {v}" if isinstance(v, str) else f"{key}: {float(v):.17e}")
    return "{" + ", ".join(items) + "}"


@dataclass(frozen=True)
class Played:
    """One evaluation: per-goal success (goal order), the summary of ``agents.evaluate``."""

    success: tuple[bool, ...]
    summary: dict[str, Any]


def play(env_id: str, integrator: str, n_episodes: int, seed: int, out: Path) -> Played:
    """The shipped model of ``env_id`` on its id with ``integrator`` (the registered one is
    played without task keywords, so it is the benchmark run itself)."""
    import yaml

    from agents.evaluate import main as evaluate_main

    argv = ["--model", env_id, "--n-episodes", str(n_episodes), "--seed", str(seed),
            "--no-plots", "--out", str(out), "--force"]
    if integrator != registered_integrator(env_id):
        overrides = flow_mapping(hand_overrides(env_id, integrator))
        argv += ["--task-kwargs", f"hand_overrides:{overrides}"]
    with contextlib.redirect_stdout(io.StringIO()):
        summary = evaluate_main(argv)
    with (out / "results.yml").open() as fh:
        episodes = yaml.safe_load(fh)["episodes"]
    return Played(tuple(bool(e["success"]) for e in episodes), summary)


def format_table(rows: dict[str, dict[str, Played]]) -> str:
    """Markdown table, one line per model."""
    from agents.common.metrics import wilson_interval

    head = ("| model (id) | default | goals | success RK4 (95 % CI) | success ROS2 (95 % CI) "
            "| ROS2 - RK4 | goals that differ | median error RK4 / ROS2 |")
    lines = [head, "|" + " --- |" * 8]
    for env_id, by in rows.items():
        cells = []
        for integrator in INTEGRATORS:
            s = by[integrator].success
            lo, hi = wilson_interval(sum(s), len(s))
            cells.append(f"{100 * sum(s) / len(s):.1f} % ({sum(s)}/{len(s)}; "
                         f"{100 * lo:.1f}-{100 * hi:.1f})")
        a, b = by["rk4"], by["ros2"]
        n = len(a.success)
        diff = 100 * (sum(b.success) - sum(a.success)) / n
        differ = sum(x != y for x, y in zip(a.success, b.success, strict=True))
        errors = " / ".join(
            ", ".join(f"{p.summary[k]:.3f}" for k in ("median_x_mm", "median_theta_deg")
                      if k in p.summary) for p in (a, b))
        lines.append(f"| `{env_id}` | {registered_integrator(env_id).upper()} | {n} | "
                     f"{cells[0]} | {cells[1]} | {diff:+.1f} | {differ} | {errors} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; prints the table (and writes ``--out``)."""
    from softhand_env.cli import ArgumentParser, check_output_file

    ap: argparse.ArgumentParser = ArgumentParser(prog="python benchmarks/integrator_agents.py",
                                                 description=__doc__.splitlines()[0])
    ids = shipped_ids()
    ap.add_argument("--models", nargs="+", choices=ids, default=ids, metavar="ID",
                    help="ids whose shipped default model is played (default all): "
                         + ", ".join(ids))
    ap.add_argument("--n-episodes", type=int, default=100, help="goals, 1 .. 1000 (default 100)")
    ap.add_argument("--seed", type=int, default=10000,
                    help="episode k: reset(seed=SEED + k), 0 .. 1e6 (default 10000)")
    ap.add_argument("--results", default=None,
                    help="directory of the evaluations' results.yml (default: a temporary one)")
    ap.add_argument("--out", default=None, help="also write the table to this Markdown file")
    ap.add_argument("--force", action="store_true", help="overwrite --out")
    args = ap.parse_args(argv)
    if not 1 <= args.n_episodes <= 1000:
        ap.error(f"--n-episodes must be in [1, 1000] (got {args.n_episodes})")
    if not 0 <= args.seed <= 1_000_000:
        ap.error(f"--seed must be in [0, 1000000] (got {args.seed})")
    if args.out is not None:
        check_output_file(args.out, args.force)
    rows: dict[str, dict[str, Played]] = {}
    with contextlib.ExitStack() as stack:
        results = (Path(args.results) if args.results is not None
                   else Path(stack.enter_context(tempfile.TemporaryDirectory())))
        for env_id in args.models:
            rows[env_id] = {}
            for integrator in INTEGRATORS:
                p = play(env_id, integrator, args.n_episodes, args.seed,
                         results / env_id / integrator)
                rows[env_id][integrator] = p
                print(f"{env_id} {integrator}: {sum(p.success)}/{len(p.success)}",
                      file=sys.stderr, flush=True)
    table = format_table(rows)
    print(table)
    if args.out is not None:
        Path(args.out).write_text(table + "\n")
    return 0


if __name__ == "__main__":
    from softhand_env.cli import run_cli

    raise SystemExit(run_cli(main))
