"""Evaluate a scripted policy or a trained model on a fixed, seeded goal set (RL Zoo's ``enjoy``).

::

    python -m agents.evaluate --model agents/models/SoftHandReorient-v0
    python -m agents.evaluate --policy model-based --env SoftHandTranslate-v0
    python -m agents.evaluate --policy paper            # SoftHand-v0, the chapter-5 motions
    python -m agents.evaluate --policy handling --grasp-deg 4.8 --n-episodes 1

Episode k of the goal set starts with ``reset(seed=SEED + k)`` (default ``--seed 10000
--n-episodes 100``: the test goals; training validates on seed 5000). Success is the benchmark's:
|x - x*| < 1 mm and/or |theta - theta*| < 1 deg (the task's targets) at the END of the
episode (``info["is_success"]`` of the last step, with ``x_tolerance_mm=1.0,
theta_tolerance_deg=1.0`` set on the env). A model is played deterministically with the
``gym.make`` keywords of its run (``config.yml``) and its frozen VecNormalize statistics; a
scripted policy with the keywords it declares (``env_kwargs``, ``episode_steps``).

With ``--goals FILE`` (a JSON list of goals in the task's SI units, see ``--help``) episode k
plays goal k instead, ``reset(seed=SEED + k, options={"goal": goal_k})``, for models and
scripted policies alike.

The registered id defines the task: a model is played with its config's agent keywords
(control period, action mapping, observation layout) on the id's task keywords (goal ranges,
tolerances, episode duration, hand, randomisation, sensor model); a config that sets a task
keyword otherwise is refused (:mod:`agents.runs.task_keywords`). ``--task-kwargs KEY:VALUE``
sets task keywords on purpose; the table and ``results.yml`` then say ``benchmark: false``
and name them.

A model is refused (one line, exit code 2) on an env whose signature differs from its run's
(:mod:`softhand_env.envs.signature`: env id, sensor model, observation layout, ...), e.g. a
``-v0`` model on its ``-v1`` id. ``--allow-off-signature`` plays it anyway (``--env`` may then
name another id of the model's task): the table's title says ``NOT the benchmark:
off-signature`` with the differing fields, and ``results.yml`` says ``benchmark: false`` and
lists them under ``off_signature`` (fields passed over with ``--ignore-signature`` are listed
too). The observation and action shapes must still match.

Every success rate is printed and recorded with its Wilson 95 % score interval; the table
also gives the strict success rate (within 0.5 mm / 0.5 deg at the end of a successful
episode). A model scored on the test goals (a seeded goal set that meets seeds 10000 + k) is
counted in its run directory's ``test_scores.yml`` (count and every score; the shipped models
are not written to: their test scores are documented in ``docs/results.md``). The protocol:
choices on the validation goals (seed 5000 + k), the test goals once per final model.

With ``--ray [ADDRESS]`` the episodes are split over Ray workers (a Ray started here with this
machine's CPUs, or the cluster at ADDRESS; ``--ray-workers K`` chunks): each worker loads the
model (or builds the scripted policy) and its env itself and plays a contiguous part of the
goal set; the records are merged in goal order and equal the serial run's
(:mod:`agents.play.sharding`). A model path must then be readable by every worker.

Prints a table (success rates, final |x| and |theta| errors, return, episode length) and writes
to ``--out`` (default ``logs/eval/<env id>/<model run or policy>``; earlier results are never
overwritten without ``--force``): ``results.yml`` (summary and every
episode), ``trajectories.png`` (object x, theta and set-points over time) and ``episode.gif``
(the ``--gif-episode`` episode, by default the successful one in which the object moves most,
rendered from ``render_mode="rgb_array"`` frames with the time, goal and object pose drawn on).
``--out`` is checked (a directory, writable, none of these files there unless ``--force``)
before the model is loaded.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.cli import (
    SEED_MAX,
    ArgumentParser,
    UserError,
    check_output_dir,
    check_range,
    parse_kv,
    run_cli,
)
from agents.common.env_factory import goal_seeds, make_env, task_targets
from agents.common.metrics import (
    ERROR_KEYS,
    STRICT_TOLERANCE,
    SUCCESS_TOLERANCE,
    success_count,
    success_text,
)
from agents.play.choice import SCRIPTED, PolicyChoice, build
from agents.play.rollout import (
    EvaluationResults,
    chunks_of,
    evaluate,
    play_chunk,
    run_episode,
    summarize_episodes,
)
from agents.play.sharding import add_ray_options, map_chunks, merge, ray_options, worker_count
from agents.play.test_scores import is_shipped, plays_test_goals, read_scores, record_score
from agents.plots.episodes import (
    choose_episode,
    evaluation_title,
    gif_frames,
    plot_episodes,
)
from agents.runs.layout import TEST_SCORES_FILE
from agents.runs.loading import ModelPolicy
from softhand_env.envs.signature import SIGNATURE_FIELDS


@dataclass
class EvaluateSettings:
    """The evaluation command line (``python -m agents.evaluate --help``), range-checked:
    ``model`` or ``policy`` (exactly one), the env id, the grasp angle of ``handling`` (deg),
    ``n_episodes`` goals from ``seed`` (or the goals of the JSON file ``goals``), sampling
    (``stochastic``), the output directory and what goes in it, the env-signature fields not
    to check or ``allow_off_signature`` (play a model off its signature, labelled), and how
    a model is loaded (``trust_model``, torch device and threads)."""

    model: str | None = None
    policy: str | None = None
    env: str | None = None
    grasp_deg: float = 6.0
    n_episodes: int = 100
    seed: int = 10000
    goals: str | None = None
    stochastic: bool = False
    out: str | None = None
    force: bool = False
    no_plots: bool = False
    gif_episode: int | None = None
    gif_size: int = 240
    ignore_signature: list[str] = dataclasses.field(default_factory=list)
    task_kwargs: list[str] = dataclasses.field(default_factory=list)
    allow_off_signature: bool = False
    trust_model: bool = False
    device: str = "cpu"
    torch_threads: int = 1
    ray: str | None = None
    ray_workers: int | None = None

    def __post_init__(self) -> None:
        """Range checks (UserError on a bad value; ``--ray`` without Ray installed too)."""
        self.sharding = ray_options(self.ray, self.ray_workers)
        check_range("--n-episodes", self.n_episodes, 1, 100_000)
        check_range("--seed", self.seed, 0, SEED_MAX - self.n_episodes)
        check_range("--torch-threads", self.torch_threads, 1, 256)
        check_range("--gif-size", self.gif_size, 16, 2048)
        check_range("--grasp-deg", self.grasp_deg, 0.0, 30.0)
        if self.allow_off_signature and self.model is None:
            raise UserError("--allow-off-signature applies to --model (a scripted policy has "
                            "no signature)")

    def choice(self) -> PolicyChoice:
        """The policy to play."""
        return PolicyChoice(model=self.model, policy=self.policy, env=self.env,
                            grasp_deg=self.grasp_deg, device=self.device,
                            trust_model=self.trust_model,
                            task_kwargs=parse_kv(self.task_kwargs, "--task-kwargs"),
                            allow_off_signature=self.allow_off_signature)


def parse_args(argv: Sequence[str] | None = None) -> EvaluateSettings:
    """Command-line arguments (see ``python -m agents.evaluate --help``)."""
    p = ArgumentParser(prog="python -m agents.evaluate", description=__doc__.split("\n\n")[0])
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--model", help="saved model: the env id of a shipped model, a run "
                     "directory (RL Zoo layout: <env id>.zip, <env id>/config.yml) or a .zip "
                     "in it")
    who.add_argument("--policy", choices=SCRIPTED, help="scripted policy (agents.scripted)")
    p.add_argument("--env", default=None,
                   help="env id (model: taken from its config; paper/handling: SoftHand-v0)")
    p.add_argument("--grasp-deg", type=float, default=6.0, help="handling: grasp angle (deg)")
    p.add_argument("--n-episodes", type=int, default=100, help="goals, 1 .. 100000")
    p.add_argument("--seed", type=int, default=10000,
                   help="episode k: reset(seed=SEED + k); 0 .. 2**32 - 1 - n_episodes")
    p.add_argument("--goals", default=None, metavar="FILE",
                   help="play these goals instead of seeded ones: a JSON list, one goal per "
                        "episode, each a list in the task's SI units as reset(options={'goal': "
                        "...}) takes it: [x (m)] for Translate, [theta (rad)] for Reorient, "
                        "[x (m), theta (rad)] for Pose (a bare number for the 1-D tasks); "
                        "episode k starts with reset(seed=SEED + k, options={'goal': goal k})")
    p.add_argument("--stochastic", action="store_true", help="sample model actions")
    p.add_argument("--out", default=None,
                   help="output directory (default logs/eval/<env id>/<model run or policy>); "
                        "existing results (results.yml, trajectories.png, episode.gif) are "
                        "never overwritten without --force")
    p.add_argument("--force", action="store_true", help="overwrite earlier results in --out")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG and the GIF")
    p.add_argument("--gif-episode", type=int, default=None,
                   help="episode index to animate (default: the successful episode in which "
                        "the object moves most)")
    p.add_argument("--gif-size", type=int, default=240, help="GIF frame size (px)")
    p.add_argument("--ignore-signature", nargs="+", default=[], metavar="FIELD",
                   help="model: env-signature fields not to check (e.g. version)")
    p.add_argument("--task-kwargs", nargs="+", default=[], metavar="KEY:VALUE",
                   help="task keywords to evaluate on instead of the id's (goal ranges, "
                        "tolerances, max_episode_steps, hand, rand_*...): the results are "
                        "labelled benchmark: false")
    p.add_argument("--allow-off-signature", action="store_true",
                   help="model: play it on an env whose signature differs from its run's "
                        "(--env may name another id of its task, e.g. the -v1 id of a -v0 "
                        "model): printed and recorded as off-signature, benchmark: false")
    p.add_argument("--trust-model", action="store_true",
                   help="model: also load what only unpickling can read (zip entries that cannot "
                        "be rebuilt, vecnormalize.pkl without .npz): runs code from the files")
    p.add_argument("--device", default="cpu", choices=("cpu", "cuda", "auto"))
    p.add_argument("--torch-threads", type=int, default=1, help="1 .. 256")
    add_ray_options(p)
    ns = p.parse_args(argv)
    return EvaluateSettings(**{f.name: getattr(ns, f.name)
                               for f in dataclasses.fields(EvaluateSettings)})


# --------------------------------------------------------------------------------- output
def tolerance_text(targets: Sequence[str], strict: bool) -> str:
    """The tolerance of a success rule on the task's coordinates, e.g. ``"1 mm"`` (Translate),
    ``"0.5 mm / 0.5 deg"`` (Pose, ``strict``): the benchmark's rule
    (:data:`~agents.common.metrics.SUCCESS_TOLERANCE`) or the strict one
    (:data:`~agents.common.metrics.STRICT_TOLERANCE`); ``"the task's rule"`` for the
    goal-free task."""
    units = {"x": "mm", "theta": "deg"}
    values = {t: STRICT_TOLERANCE[t] if strict else SUCCESS_TOLERANCE[t][1] for t in targets}
    return " / ".join(f"{values[t]:g} {units[t]}" for t in targets) or "the task's rule"


def format_table(title: str, summary: dict[str, float], targets: Sequence[str]) -> str:
    """A plain-text table of a summary: each success rate with its count and Wilson 95 %
    interval (:func:`~agents.common.metrics.success_text`): the benchmark's (1 mm / 1 deg on
    the task's coordinates) and, when the summary has it, the strict one (0.5 mm / 0.5 deg,
    :func:`~agents.common.metrics.strict_success`) next to it; ``targets`` are the task's
    coordinates (``"x"``, ``"theta"``)."""
    n = int(summary["n_episodes"])
    rows = [("episodes", f"{n:d}"),
            (f"success rate ({tolerance_text(targets, strict=False)})",
             success_text(success_count(summary["success_rate"], n), n))]
    if "success_strict" in summary:
        rows.append((f"success rate, strict ({tolerance_text(targets, strict=True)})",
                     success_text(success_count(summary["success_strict"], n), n)))
    units = {"x": ("|x err|", "mm"), "theta": ("|theta err|", "deg")}
    for t in targets:
        label, unit = units[t]
        key = ERROR_KEYS[t]
        rows.append((f"final {label} median / mean / max",
                     f"{summary[f'median_{key}']:.3f} / {summary[f'mean_{key}']:.3f} / "
                     f"{summary[f'max_{key}']:.3f} {unit}"))
    rows += [("return (mean)", f"{summary['mean_return']:.2f}"),
             ("episode length (mean)", f"{summary['mean_length']:.1f}"),
             ("failures (grasp lost etc.)", f"{summary['n_failures']:d}")]
    if "max_friction_ratio" in summary:
        rows.append(("friction needed (max |J_t| / J_n)", f"{summary['max_friction_ratio']:.3f}"))
    width = max(len(r[0]) for r in rows)
    lines = [title, "-" * len(title)] + [f"{a:<{width}}  {b}" for a, b in rows]
    return "\n".join(lines)


def write_gif(path: Path, env_id: str, kwargs: dict[str, Any], wrapper: Any, policy: Any,
              seed: int, size: int, deterministic: bool = True, fps: int = 25,
              goal: Sequence[float] | None = None) -> None:
    """Replay one episode with ``render_mode="rgb_array"`` and save it as a GIF (``fps``), the
    time, goal and object pose drawn on every frame."""
    import imageio.v2 as imageio

    env = make_env(env_id, kwargs, wrapper, render_mode="rgb_array", render_width=size,
                   render_height=size)
    frames: list = []
    ep = run_episode(env, policy, seed, deterministic, frames, goal)
    env.close()
    shown, duration = gif_frames(frames, env.unwrapped.dt,  # type: ignore[attr-defined]
                                 task_targets(env_id), ep["goal"],
                                 ep["pose"], fps)
    images: list[Any] = shown
    imageio.mimsave(path, images, duration=duration, loop=0)


#: Largest ``--goals`` file (bytes).
MAX_GOALS_BYTES = 20_000_000


def read_goals(path: str, targets: Sequence[str]) -> list[list[float]]:
    """Goals of a ``--goals`` file: a JSON list, each goal a list of ``len(targets)`` finite
    numbers in SI units (a bare number for a 1-D task); :class:`UserError` otherwise."""

    if not targets:
        raise UserError("--goals needs a goal task (SoftHandTranslate/Reorient/Pose-v0)")
    from agents.runs.model_files import load_json_bounded

    try:
        with open(path, "rb") as fh:
            text = fh.read(MAX_GOALS_BYTES + 1)
        if len(text) > MAX_GOALS_BYTES:
            raise UserError(f"--goals: {path} is larger than {MAX_GOALS_BYTES} bytes")
        data = load_json_bounded(text, f"--goals {path}", limit=3)
    except OSError as exc:
        raise UserError(f"--goals: cannot read {path}: {exc.strerror}") from None
    except ValueError as exc:
        raise UserError(f"--goals: {path} is not JSON of goals: {str(exc)[:200]}") from None
    if not isinstance(data, list) or not data or len(data) > 100_000:
        raise UserError(f"--goals: {path} must hold a JSON list of 1 .. 100000 goals")
    units = {"x": "x (m)", "theta": "theta (rad)"}
    want = "[" + ", ".join(units[t] for t in targets) + "]"
    goals = []
    for k, g in enumerate(data):
        g = [g] if isinstance(g, (int, float)) and not isinstance(g, bool) else g
        ok = (isinstance(g, list) and len(g) == len(targets)
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in g))
        if not ok or not np.all(np.isfinite(np.asarray(g, dtype=float))):
            raise UserError(f"--goals: goal {k} is {data[k]!r}; each goal must be {want}, finite")
        goals.append([float(v) for v in g])
    return goals


def check_goal_range(env: Any, goals: Sequence[Sequence[float]]) -> None:
    """:class:`UserError` for a goal outside the task's goal range ``[-goal_range, goal_range]``
    per coordinate (the range the env samples from; read from the env's task when it has one,
    else left to the env's own ``reset`` validation)."""
    targets = getattr(getattr(env.unwrapped, "task", None), "targets", None)
    found = [getattr(t, "goal_range", None) for t in targets or ()]
    ranges = [float(r) for r in found if r is not None]
    if not ranges or len(ranges) != len(found):
        return
    for k, goal in enumerate(goals):
        for value, r in zip(goal, ranges, strict=True):
            if abs(value) > r:
                raise UserError(f"--goals: goal {k} = {list(goal)} is outside the task's range "
                                f"(|goal| <= {[float(x) for x in ranges]}, SI units)")


def output_dir(args: EvaluateSettings, env_id: str, policy: Any) -> Path:
    """``--out``, or ``logs/eval/<env id>/<run dir>_<model>`` for a model (a distinct
    directory per model file), ``logs/eval/<env id>/<policy>`` for a scripted policy."""
    if args.out is not None:
        return Path(args.out)
    if isinstance(policy, ModelPolicy):
        run = policy.run
        name = f"{run.algo}_{run.run_dir.name}_{run.zip_path.stem}"
    else:
        name = (str(args.policy) if args.policy != "handling"
                else f"handling_{args.grasp_deg:g}deg")
    return Path("logs") / "eval" / env_id / name


def output_files(no_plots: bool) -> tuple[str, ...]:
    """The files an evaluation writes into its output directory."""
    return ("results.yml",) if no_plots else ("results.yml", "trajectories.png", "episode.gif")


def check_output(out: Path, force: bool, no_plots: bool = False) -> None:
    """:class:`UserError` if ``out`` is a file, holds one of the files this evaluation writes
    (:func:`output_files`) and ``force`` is not set, or cannot be written; nothing is
    created."""
    check_output_dir(out, output_files(no_plots), force)


def main(argv: Sequence[str] | None = None) -> dict[str, float]:
    """CLI entry point; returns the summary."""
    args = parse_args(argv)
    unknown = sorted(set(args.ignore_signature) - set(SIGNATURE_FIELDS))
    if unknown:
        raise UserError(f"--ignore-signature: unknown field(s) {', '.join(unknown)}; fields: "
                        + ", ".join(SIGNATURE_FIELDS))
    if args.out is not None:  # before the model is loaded
        check_output(Path(args.out), args.force, args.no_plots)
    import torch

    torch.set_num_threads(args.torch_threads)
    policy, env_id, kwargs, wrapper, name = build(args.choice())
    targets = task_targets(env_id)
    goals = None
    n_episodes = args.n_episodes
    if args.goals is not None:
        goals = read_goals(args.goals, targets)
        n_episodes = len(goals)
        check_range("--seed", args.seed, 0, SEED_MAX - n_episodes)
    if args.gif_episode is not None and not 0 <= args.gif_episode < n_episodes:
        raise UserError("--gif-episode must index one of the episodes")
    out = output_dir(args, env_id, policy)
    check_output(out, args.force, args.no_plots)
    env = make_env(env_id, kwargs, wrapper)
    if goals is not None:
        check_goal_range(env, goals)
    off_signature: dict[str, str] = {}
    if isinstance(policy, ModelPolicy):
        off_signature = policy.check_env(env, args.ignore_signature, args.allow_off_signature)
    counted = isinstance(policy, ModelPolicy) and plays_test_goals(args.seed, n_episodes,
                                                                   args.goals)
    if counted and not is_shipped(policy.run.run_dir):
        read_scores(policy.run.run_dir)  # a corrupt record is refused before playing
    seeds = goal_seeds(args.seed, n_episodes)
    if args.sharding.address is None:
        summary, episodes = evaluate(env, policy, seeds, targets, not args.stochastic, goals)
    else:
        summary, episodes = evaluate_sharded(args, seeds, targets, goals)
    if goals is None:
        title = evaluation_title(env_id, name, n_episodes, args.seed, targets)
    else:
        title = f"{env_id}, {name} policy, {n_episodes} goals from {args.goals}"
    overrides = args.choice().task_kwargs
    title += not_benchmark_label(overrides, off_signature)
    print(format_table(title, summary, targets))
    out.mkdir(parents=True, exist_ok=True)
    results = EvaluationResults(env_id=env_id, policy=str(args.model or args.policy),
                                env_kwargs=kwargs, env_wrapper=wrapper, seed=args.seed,
                                goals_file=args.goals, summary=summary, episodes=episodes,
                                task_overrides=overrides,
                                off_signature=list(off_signature.values()))
    with (out / "results.yml").open("w") as fh:
        yaml.safe_dump(results.to_yaml(), fh, sort_keys=False)
    if not args.no_plots:
        shown = choose_episode(episodes) if args.gif_episode is None else args.gif_episode
        plot_episodes(out / "trajectories.png", episodes, targets,
                      env.unwrapped.dt, title, shown)  # type: ignore[attr-defined]
        write_gif(out / "episode.gif", env_id, kwargs, wrapper, policy, seeds[shown],
                  args.gif_size, not args.stochastic,
                  goal=None if goals is None else goals[shown])
    env.close()
    print(f"wrote {out}/results.yml" + ("" if args.no_plots else ", trajectories.png, episode.gif"))
    if counted:
        count_test_score(policy, n_episodes, args.seed, summary)
    return summary


def not_benchmark_label(overrides: dict[str, Any], off_signature: dict[str, str]) -> str:
    """What a table title adds for an evaluation that is not the benchmark's: the task
    keywords set on purpose and the signature fields the model was played off (empty string
    for a benchmark evaluation)."""
    parts = []
    if overrides:
        parts.append("task keywords " + ", ".join(f"{k}={v!r}"
                                                  for k, v in sorted(overrides.items())))
    if off_signature:
        parts.append("off-signature, " + "; ".join(off_signature.values()))
    return " -- NOT the benchmark: " + " | ".join(parts) if parts else ""


def evaluate_sharded(args: EvaluateSettings, seeds: Sequence[int], targets: Sequence[str],
                     goals: Sequence[Sequence[float]] | None
                     ) -> tuple[dict[str, float], list[dict[str, Any]]]:
    """:func:`~agents.play.rollout.evaluate` with the episodes split over Ray workers
    (``--ray``; :mod:`agents.play.sharding`): each worker builds the policy and env of the
    command line's choice and plays a contiguous part of the goal set; the records are merged
    in goal order, so summary and records equal the serial run's."""
    options = args.sharding
    n_chunks = worker_count(options, len(seeds))
    chunks = chunks_of(args.choice(), seeds, n_chunks, goals, deterministic=not args.stochastic,
                       torch_threads=args.torch_threads)
    episodes = merge(map_chunks(play_chunk, chunks, options.address, options.workers))
    return summarize_episodes(episodes, targets), episodes


def count_test_score(policy: ModelPolicy, n_episodes: int, seed: int,
                     summary: dict[str, float]) -> None:
    """Record a test score in the model's run directory (``test_scores.yml``) and say so; a
    shipped model is not written to."""
    run_dir = policy.run.run_dir
    if is_shipped(run_dir):
        print("shipped model: its test scores are documented in docs/results.md "
              "(nothing recorded)")
        return
    try:
        data = record_score(run_dir, policy.run.zip_path.name, n_episodes, seed, summary)
    except OSError as exc:
        raise UserError(f"cannot record the test score in {run_dir / TEST_SCORES_FILE}: "
                        f"{exc.strerror}") from None
    times = "once" if data["count"] == 1 else f"{data['count']} times"
    print(f"test goals: this run has been scored on them {times} "
          f"({run_dir / TEST_SCORES_FILE}); choices belong on the validation goals (seed 5000)")


if __name__ == "__main__":
    run_cli(main)
