"""Compare Pose policies: reachable set over a goal grid, and one manoeuvre.

::

    python -m agents.pose_figures --policy loop-plan --model SoftHandPose-v0 --out out/pose
    python -m agents.pose_figures --model logs/ppo/SoftHandPose-v0_3 --out out/pose --grid 21
    python -m agents.pose_figures --env SoftHandPose-v1 --policy loop-plan \
        --model SoftHandPose-v1 --out out/pose_v1

Each ``--model`` (a run directory or registered id, as ``agents.evaluate --model`` takes it) or
``--policy`` (a scripted goal policy) is one policy, in the order given; each is played
deterministically on ``--env`` (a Pose id, default ``SoftHandPose-v0``; a model must have
been trained on it) in its own env (:func:`agents.play.choice.build`: the run's ``gym.make``
keywords and wrappers, the benchmark's 1 mm / 1 deg tolerance), with the goal range widened to
``--span-mm`` / ``--span-deg`` so that goals outside the task's +-10 mm / +-10 deg can be set.

With ``--ray [ADDRESS]`` (``--ray-workers K``) each policy's grid is split over Ray workers,
each building the policy and its env itself (:mod:`agents.play.sharding`); the results equal
the serial run's (``seconds`` is then the wall-clock of the sharded grid).

Writes to ``--out`` (files already there are refused without ``--force``):

* ``reachable.png`` / ``reachable.npz``: one episode per goal on a ``--grid`` x ``--grid`` grid
  over x* in [-span_mm, span_mm] and theta* in [-span_deg, span_deg]; episode k (flat index
  ``i_theta * grid + i_x``) starts with ``reset(seed=GOAL_SEED + k, options={"goal": [x*,
  theta*]})``. Its outcome: ``success`` (``is_success`` of the last step: within tolerance,
  grasped, no failure), the env's ``termination_reason`` of the last step (a failure), or
  ``time`` (ran to the time limit out of tolerance). See :func:`save_npz` for the arrays.
* ``manoeuvre.png``: for one goal (``--goal-x-mm``, ``--goal-theta-deg``; by default far off
  the rotation-coupled line theta* = 0.77 x*), each policy's finger set-point path in (rotate,
  squeeze) coordinates and the object x, theta over time (seed ``GOAL_SEED``).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.cli import (
    SEED_MAX,
    ArgumentParser,
    UserError,
    check_output_dir,
    check_range,
    run_cli,
)
from agents.common.env_factory import make_env
from agents.common.metrics import SUCCESS_TOLERANCE, is_failure
from agents.play.choice import PolicyChoice, build
from agents.play.rollout import chunks_of, play_chunk, run_episode
from agents.play.sharding import (
    RayOptions,
    add_ray_options,
    map_chunks,
    merge,
    ray_options,
    worker_count,
)
from agents.plots.pose import OUTCOMES, Manoeuvre, in_box, plot_manoeuvre, plot_reachable, rate
from agents.runs.loading import ModelPolicy
from softhand_env.envs.task_configs import load_task_config

ENV_ID = "SoftHandPose-v0"
#: Ids of the Pose task the figures can be drawn on (``--env``).
POSE_IDS = ("SoftHandPose-v0", "SoftHandPose-v1", "SoftHandPoseRandom-v0",
            "SoftHandPoseRandom-v1")
#: Scripted policies that play a pose goal (``agents.evaluate --policy``).
GOAL_POLICIES = ("loop-plan", "model-based")
#: Files written to ``--out``.
OUTPUTS = ("reachable.png", "reachable.npz", "manoeuvre.png")
MAX_POLICIES = 8


class _AddPolicy(argparse.Action):
    """Append ``(kind, value)`` to one list, so ``--model`` and ``--policy`` keep their order."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option_string: Any = None):
        items = list(getattr(namespace, self.dest, None) or [])
        items.append((self.const, values))
        setattr(namespace, self.dest, items)


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Command-line arguments (see ``python -m agents.pose_figures --help``)."""
    p = ArgumentParser(prog="python -m agents.pose_figures",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--model", dest="policies", action=_AddPolicy, const="model",
                   metavar="PATH_OR_ID", help="saved model (as agents.evaluate --model); "
                   "repeatable")
    p.add_argument("--policy", dest="policies", action=_AddPolicy, const="policy",
                   choices=GOAL_POLICIES, help="scripted policy; repeatable")
    p.add_argument("--env", default=ENV_ID, choices=POSE_IDS,
                   help=f"Pose id the policies play (default {ENV_ID})")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--force", action="store_true", help="overwrite earlier figures in --out")
    p.add_argument("--grid", type=int, default=31,
                   help="goals per axis, 2 .. 101 (default 31: 1 mm / 1 deg steps at the "
                        "default spans)")
    p.add_argument("--span-mm", type=float, default=15.0,
                   help="grid x* in [-span, span] (mm), 0.5 .. 100 (default 15)")
    p.add_argument("--span-deg", type=float, default=15.0,
                   help="grid theta* in [-span, span] (deg), 0.5 .. 90 (default 15)")
    p.add_argument("--goal-seed", type=int, default=20000,
                   help="episode k: reset(seed=GOAL_SEED + k); 0 .. 2**32 - 1 - grid**2 (default "
                        "20000: apart from the training, validation and test goals)")
    p.add_argument("--goal-x-mm", type=float, default=-6.0,
                   help="manoeuvre goal x* (mm), within +-span-mm (default -6)")
    p.add_argument("--goal-theta-deg", type=float, default=8.0,
                   help="manoeuvre goal theta* (deg), within +-span-deg (default 8)")
    p.add_argument("--trust-model", action="store_true",
                   help="models: also load what only unpickling can read (as agents.evaluate)")
    add_ray_options(p)
    args = p.parse_args(argv)
    args.policies = args.policies or []
    if not args.policies:
        raise UserError("give at least one --model or --policy")
    check_range("number of --model/--policy", len(args.policies), 1, MAX_POLICIES)
    check_range("--grid", args.grid, 2, 101)
    check_range("--span-mm", args.span_mm, 0.5, 100.0)
    check_range("--span-deg", args.span_deg, 0.5, 90.0)
    check_range("--goal-seed", args.goal_seed, 0, SEED_MAX - args.grid**2)
    check_range("--goal-x-mm", args.goal_x_mm, -args.span_mm, args.span_mm)
    check_range("--goal-theta-deg", args.goal_theta_deg, -args.span_deg, args.span_deg)
    args.sharding = ray_options(args.ray, args.ray_workers)
    return args


# ---------------------------------------------------------------------------------- setup
@dataclass
class Contender:
    """One policy and the env it plays in (the goal range widened to the grid's span)."""

    label: str
    spec: str  # "--model X" or "--policy Y"
    policy: Any
    env: Any

    @property
    def dt(self) -> float:
        """Control period (s)."""
        return float(self.env.unwrapped.dt)


def contender_choice(kind: str, value: str, trust_model: bool = False,
                     env_id: str = ENV_ID) -> PolicyChoice:
    """The :class:`~agents.play.choice.PolicyChoice` of a ``--model``/``--policy`` entry on
    ``env_id`` (one of :data:`POSE_IDS`)."""
    return PolicyChoice(model=value if kind == "model" else None,
                        policy=value if kind == "policy" else None, env=env_id,
                        grasp_deg=6.0, device="cpu", trust_model=trust_model)


def span_kwargs(span_mm: float, span_deg: float) -> dict[str, float]:
    """The goal-range keywords that let the grid's goals be set (mm, deg)."""
    return {"goal_x_range_mm": span_mm, "goal_theta_range_deg": span_deg}


def make_contender(kind: str, value: str, span_mm: float, span_deg: float,
                   trust_model: bool = False, env_id: str = ENV_ID) -> Contender:
    """Build a ``--model``/``--policy`` entry through :func:`agents.play.choice.build` (as
    ``agents.evaluate`` does) and its env with :func:`span_kwargs` added."""
    policy, env_id, kwargs, wrapper, name = build(contender_choice(kind, value, trust_model,
                                                                    env_id))
    env = make_env(env_id, {**kwargs, **span_kwargs(span_mm, span_deg)}, wrapper)
    if isinstance(policy, ModelPolicy):
        policy.check_env(env)
        name = f"{policy.algo} {policy.run.run_dir.name}"
    return Contender(name, f"--{kind} {value}", policy, env)


def outcome_of(episode: dict[str, Any]) -> str:
    """Outcome of an :func:`agents.play.rollout.run_episode` record (see the module doc)."""
    if episode["success"]:
        return "success"
    reason = episode["termination_reason"]
    return str(reason) if is_failure(reason) else "time"


# --------------------------------------------------------------------------------- runs
def goal_grid(grid: int, span_mm: float, span_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid axes: x* (grid,) in mm and theta* (grid,) in deg, from -span to span."""
    return np.linspace(-span_mm, span_mm, grid), np.linspace(-span_deg, span_deg, grid)


def grid_goals(goal_x_mm: np.ndarray, goal_theta_deg: np.ndarray, goal_seed: int
               ) -> tuple[list[int], list[tuple[float, float]]]:
    """Seeds and goals (x* m, theta* rad) of the grid's episodes in flat order
    (``i_theta * G_x + i_x``)."""
    seeds, goals = [], []
    for i, th in enumerate(goal_theta_deg):
        for j, x in enumerate(goal_x_mm):
            seeds.append(goal_seed + i * len(goal_x_mm) + j)
            goals.append((float(x) * 1e-3, math.radians(float(th))))
    return seeds, goals


def grid_arrays(episodes: Sequence[dict[str, Any]], shape: tuple[int, int]
                ) -> dict[str, np.ndarray]:
    """The grid results of the episode records (flat order, :func:`grid_goals`):
    ``outcome`` (G_theta, G_x) str, ``success`` (G_theta, G_x) bool, ``final_pose``
    (G_theta, G_x, 3) (m, m, rad), ``length`` (G_theta, G_x) control steps."""
    out = {"outcome": np.empty(shape, dtype=f"<U{max(map(len, OUTCOMES)) + 8}"),
           "success": np.zeros(shape, dtype=bool),
           "final_pose": np.zeros((*shape, 3)),
           "length": np.zeros(shape, dtype=np.int64)}
    for k, ep in enumerate(episodes):
        i, j = divmod(k, shape[1])
        out["outcome"][i, j] = outcome_of(ep)
        out["success"][i, j] = ep["success"]
        out["final_pose"][i, j] = ep["final_pose"]
        out["length"][i, j] = ep["length"]
    return out


def run_grid(c: Contender, goal_x_mm: np.ndarray, goal_theta_deg: np.ndarray,
             goal_seed: int) -> dict[str, np.ndarray]:
    """One episode per grid goal (:func:`grid_goals`) in ``c``'s env; returns
    :func:`grid_arrays`."""
    seeds, goals = grid_goals(goal_x_mm, goal_theta_deg, goal_seed)
    episodes = [run_episode(c.env, c.policy, seed, goal=goal)
                for seed, goal in zip(seeds, goals, strict=True)]
    return grid_arrays(episodes, (len(goal_theta_deg), len(goal_x_mm)))


def run_grid_sharded(choice: PolicyChoice, span: dict[str, float], goal_x_mm: np.ndarray,
                     goal_theta_deg: np.ndarray, goal_seed: int, options: RayOptions
                     ) -> dict[str, np.ndarray]:
    """:func:`run_grid` with the episodes split over Ray workers (``--ray``): each worker
    builds the policy of ``choice`` and its env (``span``: :func:`span_kwargs`) and plays a
    contiguous part of the grid; merged in grid order, the arrays equal the serial run's."""
    seeds, goals = grid_goals(goal_x_mm, goal_theta_deg, goal_seed)
    chunks = chunks_of(choice, seeds, worker_count(options, len(seeds)), goals,
                       env_kwargs=span, trajectories=False)
    episodes = merge(map_chunks(play_chunk, chunks, options.address, options.workers))
    return grid_arrays(episodes, (len(goal_theta_deg), len(goal_x_mm)))


def save_npz(path: Path, contenders: Sequence[Contender], goal_x_mm: np.ndarray,
             goal_theta_deg: np.ndarray, results: Sequence[dict[str, np.ndarray]],
             seconds: Sequence[float], goal_seed: int, box: tuple[float, float]) -> None:
    """Write ``reachable.npz`` (no pickled objects; P policies, G_theta x G_x goals):

    ``labels``, ``specs`` (P,) str; ``control_dt`` (P,) s; ``seconds`` (P,) wall-clock of
    each grid; ``goal_x_mm`` (G_x,), ``goal_theta_deg`` (G_theta,); ``goal`` (G_theta, G_x, 2)
    the goals as passed to ``reset`` (m, rad); ``seed`` (G_theta, G_x); ``outcome`` (P,
    G_theta, G_x) str (:data:`~agents.plots.pose.OUTCOMES`); ``success`` (P, G_theta, G_x)
    bool; ``final_pose`` (P, G_theta, G_x, 3) object x, y, theta at the end (m, m, rad);
    ``length`` (P, G_theta, G_x) control steps; ``task_box`` (2,) the task's goal range (mm,
    deg); ``tolerance`` (2,) the success tolerance (mm, deg).
    """
    gx, gt = np.meshgrid(goal_x_mm * 1e-3, np.radians(goal_theta_deg))
    n = len(goal_x_mm)
    seeds = goal_seed + np.arange(len(goal_theta_deg) * n).reshape(len(goal_theta_deg), n)
    np.savez(
        path,
        labels=np.array([c.label for c in contenders]),
        specs=np.array([c.spec for c in contenders]),
        control_dt=np.array([c.dt for c in contenders]),
        seconds=np.array(seconds, dtype=np.float64),
        goal_x_mm=goal_x_mm,
        goal_theta_deg=goal_theta_deg,
        goal=np.stack([gx, gt], axis=-1),
        seed=seeds.astype(np.int64),
        outcome=np.stack([r["outcome"] for r in results]),
        success=np.stack([r["success"] for r in results]),
        final_pose=np.stack([r["final_pose"] for r in results]),
        length=np.stack([r["length"] for r in results]),
        task_box=np.array(box, dtype=np.float64),
        tolerance=np.array([SUCCESS_TOLERANCE["x"][1], SUCCESS_TOLERANCE["theta"][1]]),
    )


def summary_line(label: str, outcome: np.ndarray, box: np.ndarray, seconds: float) -> str:
    """One line: success rates in the task box and on the grid, outcomes outside the box."""
    success = outcome == "success"
    names, counts = np.unique(outcome[~box], return_counts=True)
    outside = ", ".join(f"{n} {c}" for c, n in sorted(zip(counts, names, strict=True),
                                                      reverse=True)) or "-"
    return (f"{label}: success {100 * rate(success, box):.1f} % in the task box "
            f"({int(box.sum())} goals), {100 * rate(success):.1f} % on the grid "
            f"({success.size}); outside the box: {outside}; {seconds:.1f} s")


def check_output(out: Path, force: bool) -> None:
    """:class:`UserError` if ``out`` is a file, holds one of :data:`OUTPUTS` (without
    ``force``) or cannot be written; nothing is created."""
    check_output_dir(out, OUTPUTS, force)


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """CLI entry point; returns ``{"labels", "outcome", "seconds"}`` of the grid runs."""
    args = parse_args(argv)
    out = Path(args.out)
    check_output(out, args.force)
    if any(kind == "model" for kind, _ in args.policies):
        import torch

        torch.set_num_threads(1)
    contenders = [make_contender(kind, value, args.span_mm, args.span_deg, args.trust_model,
                                 args.env) for kind, value in args.policies]
    task = load_task_config("pose")
    box_mm, box_deg = float(task["goal_x_range_mm"]), float(task["goal_theta_range_deg"])
    goal_x_mm, goal_theta_deg = goal_grid(args.grid, args.span_mm, args.span_deg)
    inside = in_box(goal_x_mm, goal_theta_deg, box_mm, box_deg)
    results, seconds = [], []
    for (kind, value), c in zip(args.policies, contenders, strict=True):
        t0 = time.perf_counter()
        if args.sharding.address is None:
            results.append(run_grid(c, goal_x_mm, goal_theta_deg, args.goal_seed))
        else:
            results.append(run_grid_sharded(
                contender_choice(kind, value, args.trust_model, args.env),
                span_kwargs(args.span_mm, args.span_deg), goal_x_mm, goal_theta_deg,
                args.goal_seed, args.sharding))
        seconds.append(time.perf_counter() - t0)
        print(summary_line(c.label, results[-1]["outcome"], inside, seconds[-1]), flush=True)
    goal = (args.goal_x_mm * 1e-3, math.radians(args.goal_theta_deg))
    manoeuvres = []
    for c in contenders:
        ep = run_episode(c.env, c.policy, args.goal_seed, goal=goal)
        manoeuvres.append(Manoeuvre(c.label, c.dt, ep["setpoint"], ep["pose"], goal,
                                    outcome_of(ep)))
    for c in contenders:
        c.env.close()
    out.mkdir(parents=True, exist_ok=True)
    save_npz(out / "reachable.npz", contenders, goal_x_mm, goal_theta_deg, results, seconds,
             args.goal_seed, (box_mm, box_deg))
    outcome = np.stack([r["outcome"] for r in results])
    labels = [c.label for c in contenders]
    plot_reachable(out / "reachable.png", labels, outcome, goal_x_mm, goal_theta_deg, box_mm,
                   box_deg, f"{args.env}: outcome of one episode per goal\n({args.grid} x "
                   f"{args.grid} grid, seeds {args.goal_seed}..{args.goal_seed + args.grid**2 - 1}"
                   f"; success: 1 mm / 1 deg at the end)",
                   marked_goal=(args.goal_x_mm, args.goal_theta_deg))
    plot_manoeuvre(out / "manoeuvre.png", manoeuvres,
                   f"{args.env}: goal x* = {args.goal_x_mm:g} mm, theta* = "
                   f"{args.goal_theta_deg:g} deg (seed {args.goal_seed})")
    print(f"wrote {out}/" + ", ".join(OUTPUTS))
    return {"labels": labels, "outcome": outcome, "seconds": seconds}


if __name__ == "__main__":
    run_cli(main)
