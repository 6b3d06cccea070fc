"""Playing episodes: one episode from a seed (optionally a given goal) and a seeded goal set.

:func:`run_episode` plays one episode and returns its record (trajectory included);
:func:`play_episodes` the records of a goal set, :func:`summarize_episodes` their summary
(:func:`agents.common.metrics.summarize` plus failures and the friction needed), :func:`evaluate`
both; :class:`EpisodeChunk` / :func:`play_chunk` are part of a goal set as a worker plays it on
its own (:mod:`agents.play.sharding`: the env and policy built from plain data);
:class:`EvaluationResults` is what ``agents.evaluate`` writes to ``results.yml``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.common.cli import UserError
from agents.common.metrics import (
    final_errors,
    is_failure,
    strict_success,
    success_count,
    summarize,
    wilson_interval,
)
from agents.play.choice import PolicyChoice


def run_episode(
    env: Any, policy: Any, seed: int, deterministic: bool = True, frames: list | None = None,
    goal: Sequence[float] | None = None,
) -> dict[str, Any]:
    """Play one episode from ``reset(seed=seed)`` (with ``options={"goal": goal}`` if given,
    SI units, shape (goal_dim,)); returns its record (trajectory included;
    ``max_friction_ratio``: the largest step friction ratio |J_t| / J_n of either finger over
    the steps that did not end the episode with a failure other than slip, i.e. the friction
    coefficient the episode needed while the grasp held).

    ``frames``: if a list, ``env.render()`` frames are appended (``render_mode="rgb_array"``).
    """
    options = None if goal is None else {"goal": np.asarray(goal, dtype=np.float64)}
    try:
        obs, info = env.reset(seed=seed, options=options)
    except ValueError as exc:
        raise UserError(f"goal {list(goal or ())}: {exc}") from None
    poses, setpoints = [info["object_pose"]], [info["setpoint"]]
    if frames is not None:
        frames.append(env.render())
    state, start = None, np.array([True])
    ret, steps, friction = 0.0, 0, 0.0
    while True:
        action, state = policy.predict(obs, state, start, deterministic)
        start = np.array([False])
        obs, reward, terminated, truncated, info = env.step(action)
        ret += float(reward)
        steps += 1
        if info.get("termination_reason") in (None, "slip"):  # the grasp held (or slipped)
            friction = max(friction, float(np.max(info["friction_ratio"])))
        poses.append(info["object_pose"])
        setpoints.append(info["setpoint"])
        if frames is not None:
            frames.append(env.render())
        if terminated or truncated:
            break
    return {
        "seed": int(seed),
        "success": bool(info["is_success"]),
        "goal": [float(g) for g in info.get("goal", ())],
        "final_pose": [float(v) for v in info["object_pose"]],
        "return": ret,
        "length": steps,
        "termination_reason": info.get("termination_reason"),
        "max_friction_ratio": friction,
        "pose": np.array(poses),
        "setpoint": np.array(setpoints),
    }


def play_episodes(
    env: Any, policy: Any, seeds: Sequence[int], targets: Sequence[str],
    deterministic: bool = True, goals: Sequence[Sequence[float]] | None = None,
) -> list[dict[str, Any]]:
    """The records of :func:`run_episode` for every goal of ``seeds`` (episode k:
    ``seeds[k]``, with ``goals[k]`` if given), each with its final ``errors`` (mm / deg) and
    ``success_strict`` (:func:`~agents.common.metrics.strict_success`, 0.5 mm / 0.5 deg)."""
    episodes = []
    for k, seed in enumerate(seeds):
        ep = run_episode(env, policy, seed, deterministic, goal=None if goals is None else goals[k])
        info = {"object_pose": ep["final_pose"], "goal": ep["goal"]}
        ep["errors"] = final_errors(info, targets)
        ep["success_strict"] = strict_success(ep["success"], ep["errors"], targets)
        episodes.append(ep)
    return episodes


def summarize_episodes(episodes: Sequence[dict[str, Any]], targets: Sequence[str]
                       ) -> dict[str, float]:
    """The summary of :func:`play_episodes` records: besides
    :func:`~agents.common.metrics.summarize`'s keys ``success_strict`` (the rate of strict
    successes), ``n_failures`` and ``max_friction_ratio``."""
    summary = summarize(
        targets,
        [ep["success"] for ep in episodes],
        [ep["errors"] for ep in episodes],
        [ep["return"] for ep in episodes],
        [ep["length"] for ep in episodes],
    )
    summary["success_strict"] = float(np.mean([ep["success_strict"] for ep in episodes]))
    summary["n_failures"] = sum(is_failure(ep["termination_reason"]) for ep in episodes)
    summary["max_friction_ratio"] = max(ep["max_friction_ratio"] for ep in episodes)
    return summary


def evaluate(
    env: Any, policy: Any, seeds: Sequence[int], targets: Sequence[str], deterministic: bool = True,
    goals: Sequence[Sequence[float]] | None = None,
) -> tuple[dict[str, float], list[dict[str, Any]]]:
    """Play every goal of ``seeds`` (or episode k: ``seeds[k]`` with ``goals[k]``); returns the
    summary (:func:`summarize_episodes`) and the episode records (:func:`play_episodes`)."""
    episodes = play_episodes(env, policy, seeds, targets, deterministic, goals)
    return summarize_episodes(episodes, targets), episodes


@dataclass(frozen=True)
class EpisodeChunk:
    """Episodes a worker plays on its own (:mod:`agents.play.sharding`), in plain data: the
    policy choice (built again by the worker: :func:`agents.play.choice.build`), ``env_kwargs``
    added to the choice's ``gym.make`` keywords, the seeds and goals (SI units) of the
    episodes, deterministic play, torch threads (a model), and whether the records keep their
    trajectories (``pose``, ``setpoint``)."""

    choice: PolicyChoice
    seeds: tuple[int, ...]
    goals: tuple[tuple[float, ...], ...] | None = None
    env_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    deterministic: bool = True
    torch_threads: int = 1
    trajectories: bool = True


def chunks_of(choice: PolicyChoice, seeds: Sequence[int], n_chunks: int,
              goals: Sequence[Sequence[float]] | None = None, **fields: Any
              ) -> list[EpisodeChunk]:
    """The episodes ``seeds`` (with ``goals``) cut into ``n_chunks`` contiguous
    :class:`EpisodeChunk` (further fields by keyword), in order."""
    from agents.play.sharding import split

    index = split(range(len(seeds)), n_chunks)
    return [EpisodeChunk(choice, tuple(int(seeds[k]) for k in part),
                         None if goals is None else tuple(tuple(float(v) for v in goals[k])
                                                          for k in part), **fields)
            for part in index]


def play_chunk(chunk: EpisodeChunk) -> list[dict[str, Any]]:
    """:func:`play_episodes` of a chunk in an env and with a policy built here from the
    chunk's choice (the same as the serial run's, so the records are the same bit for bit)."""
    from agents.common.env_factory import make_env, task_targets
    from agents.play.choice import build

    if chunk.choice.model is not None:
        import torch

        torch.set_num_threads(chunk.torch_threads)
    policy, env_id, kwargs, wrapper, _ = build(chunk.choice)
    env = make_env(env_id, {**kwargs, **chunk.env_kwargs}, wrapper)
    try:
        episodes = play_episodes(env, policy, chunk.seeds, task_targets(env_id),
                                 chunk.deterministic, chunk.goals)
    finally:
        env.close()
    if not chunk.trajectories:
        episodes = [{k: v for k, v in ep.items() if k not in TRAJECTORY_KEYS} for ep in episodes]
    return episodes


#: Keys of an episode record that stay out of ``results.yml`` (the trajectory arrays).
TRAJECTORY_KEYS = ("pose", "setpoint")


@dataclass
class EvaluationResults:
    """An evaluation as ``results.yml`` holds it: env id, the policy (model path or scripted
    name), the ``gym.make`` keywords and wrappers it was played with, the first goal seed, the
    ``--goals`` file (None: seeded goals), the summary of :func:`evaluate` and the episode
    records (without their trajectories); ``benchmark``: whether the evaluation is the id's
    benchmark (no ``task_overrides``, no ``off_signature``)."""

    env_id: str
    policy: str
    env_kwargs: dict[str, Any]
    env_wrapper: Any
    seed: int
    goals_file: str | None
    summary: dict[str, float]
    episodes: list[dict[str, Any]]
    #: Task keywords the user set on purpose (empty: the id's task, the benchmark).
    task_overrides: dict[str, Any] = dataclasses.field(default_factory=dict)
    #: Signature fields in which the model's run differs from the env it was played on (each
    #: "field (model ..., env ...)"; empty: on its signature, or a scripted policy).
    off_signature: list[str] = dataclasses.field(default_factory=list)

    def to_yaml(self) -> dict[str, Any]:
        """The mapping written to ``results.yml`` (keys in field order)."""
        return {
            "env_id": self.env_id,
            "benchmark": not self.task_overrides and not self.off_signature,
            "task_overrides": dict(self.task_overrides),
            "off_signature": list(self.off_signature),
            "policy": self.policy,
            "env_kwargs": self.env_kwargs,
            "env_wrapper": self.env_wrapper,
            "seed": self.seed,
            "goals_file": self.goals_file,
            "summary": summary_yaml(self.summary),
            "episodes": [{k: v for k, v in ep.items() if k not in TRAJECTORY_KEYS}
                         for ep in self.episodes],
        }


def summary_yaml(summary: dict[str, float]) -> dict[str, Any]:
    """The summary as ``results.yml`` holds it: each success rate (``success_rate``,
    ``success_strict``) followed by its Wilson 95 % interval (``success_ci95``,
    ``success_strict_ci95``: ``[low, high]``, fractions)."""
    n = int(summary["n_episodes"])
    out: dict[str, Any] = {}
    for key, value in summary.items():
        out[key] = value
        if key in ("success_rate", "success_strict") and n > 0:
            ci = "success_ci95" if key == "success_rate" else "success_strict_ci95"
            out[ci] = list(wilson_interval(success_count(value, n), n))
    return out
