"""Offline datasets: a policy's episodes written as a Minari dataset (``python -m agents.collect``).

::

    python -m agents.collect --env SoftHandPose-v0 --policy SoftHandPose-v0 --episodes 1000 \\
        --dataset-id softhand/pose/expert-v0
    python -m agents.collect --env SoftHandPose-v0 --policy loop-plan --episodes 500 \\
        --dataset-id softhand/pose/loop-plan-v0 --ray --ray-workers 2
    python -m agents.collect --defaults          # every default dataset (DEFAULT_DATASETS)

``--policy`` is the id of a shipped model, a run directory (or a ``.zip`` in one), a scripted
policy (:data:`agents.play.choice.SCRIPTED`) or ``random`` (uniform actions in the env's
action space). It is resolved as ``agents.evaluate`` resolves ``--model`` / ``--policy``
(:func:`agents.play.choice.build`): a model plays deterministically on its id's task with its
run's agent keywords and wrappers, a scripted policy with the keywords it declares, ``random``
on the id's own keywords; every env gets the benchmark's success tolerance (1 mm / 1 deg).

Episode k starts with ``reset(seed=SEED + k)`` (``--seed``, default 0). Collection seeds are
training seeds: a range that meets the validation goals (seeds 5000 .. 9999) or the test goals
(10000 .. 109999) is refused.

The dataset (Minari's HDF5 format, in ``$MINARI_DATASETS_PATH/<dataset id>``, default
``~/.minari/datasets``; nothing is downloaded) holds per episode:

* ``observations`` (T + 1 entries): the env's observation as the policy received it (the
  blind observation with the run's wrapper features, e.g. the time feature; a model's own
  frozen normalisation is part of the policy and not applied), ``actions`` (T, as passed to
  ``step``, in the action space's dtype), ``rewards``, ``terminations``, ``truncations``;
* ``infos`` (T + 1 entries, the reset's first): :data:`INFO_KEYS` (object pose, goal,
  deformations, set-points, friction ratio, contact impulses, grasp and success flags, and
  ``termination_reason`` as a string, ``""`` while the episode runs);
* the episode's seed; episode metadata ``success`` and ``termination_reason`` of its end.

The dataset's ``env_spec`` is the collection env (``gym.make`` keywords and wrappers with
their keywords), so ``dataset.recover_environment()`` gives it back; ``eval_env_spec`` is the
env a policy trained on the data is evaluated on (the same agent keywords on the id's
benchmark task, :func:`agents.bc` plays it). The metadata name the policy (``algorithm_name``,
``policy``), its test-goal success where one is recorded (the shipped models' ``results.yml``,
a run's last ``test_scores.yml`` entry; None else), author, a code permalink (package version,
and the git commit of a checkout), the env signature (sensor model, observation layout, ...)
and the id's version, the seeds and the collection wall time (:func:`dataset_metadata`).

With ``--ray [ADDRESS]`` the episodes are split over Ray workers (:mod:`agents.play.sharding`):
each builds its policy and env from the command line's choice, the episodes are merged in seed
order, and the dataset equals the serial one. An existing dataset id is refused unless
``--force`` (it is then replaced once the new episodes are collected). Every input is checked
before the first episode (one line, exit code 2).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from agents.common.cli import ArgumentParser, UserError, check_range, run_cli
from agents.common.env_factory import goal_seeds, make_env, task_targets
from agents.offline.collection import (
    DEFAULT_DATASETS,
    MAX_EPISODES,
    RANDOM,
    SERIAL,
    CollectSource,
    build_source,
    check_dataset_id,
    check_seeds,
    collect_episodes,
    dataset_dir,
    dataset_metadata,
    describe,
    write_dataset,
)
from agents.play.choice import SCRIPTED
from agents.play.sharding import RayOptions, add_ray_options, ray_options


@dataclass
class CollectSettings:
    """The command line (``python -m agents.collect --help``), range-checked: the env id,
    ``--policy``, episodes and first seed, the dataset id, ``force``, torch threads, Ray
    sharding, or ``defaults`` (every :data:`DEFAULT_DATASETS` entry)."""

    env: str | None = None
    policy: str | None = None
    episodes: int | None = None
    dataset_id: str | None = None
    seed: int = 0
    force: bool = False
    defaults: bool = False
    torch_threads: int = 1
    ray: str | None = None
    ray_workers: int | None = None

    def __post_init__(self) -> None:
        """Range and combination checks (UserError)."""
        self.sharding = ray_options(self.ray, self.ray_workers)
        check_range("--torch-threads", self.torch_threads, 1, 256)
        given = [f for f, v in (("--env", self.env), ("--policy", self.policy),
                                ("--episodes", self.episodes),
                                ("--dataset-id", self.dataset_id)) if v is not None]
        if self.defaults:
            if given:
                raise UserError(f"--defaults writes the default datasets; drop {given[0]}")
        else:
            missing = [f for f in ("--env", "--policy", "--episodes", "--dataset-id")
                       if f not in given]
            if missing:
                raise UserError(f"{', '.join(missing)} needed (or --defaults)")
            assert self.episodes is not None
            check_range("--episodes", self.episodes, 1, MAX_EPISODES)
        check_range("--seed", self.seed, 0, 2**31 - 1 - MAX_EPISODES)

    def jobs(self) -> list[tuple[CollectSource, int, str]]:
        """(source, episodes, dataset id) of every dataset to write."""
        if self.defaults:
            return [(CollectSource(d.policy, d.env, self.torch_threads), d.episodes,
                     d.dataset_id) for d in DEFAULT_DATASETS]
        assert self.env and self.policy and self.episodes and self.dataset_id
        return [(CollectSource(self.policy, self.env, self.torch_threads), self.episodes,
                 self.dataset_id)]


def parse_args(argv: Sequence[str] | None = None) -> CollectSettings:
    """Command-line arguments (see ``python -m agents.collect --help``)."""
    p = ArgumentParser(prog="python -m agents.collect", description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default=None, help="env id (a soft-hand id)")
    p.add_argument("--policy", default=None,
                   help="the id of a shipped model, a run directory (or a .zip in one), a "
                        f"scripted policy ({', '.join(SCRIPTED)}) or {RANDOM}")
    p.add_argument("--episodes", type=int, default=None, help=f"episodes, 1 .. {MAX_EPISODES}")
    p.add_argument("--dataset-id", default=None,
                   help="softhand/<task>/<kind>-v<N>, <task> from the env id (pose, "
                        "translate, reorient, pose-random, pose-v1, ...)")
    p.add_argument("--seed", type=int, default=0,
                   help="episode k: reset(seed=SEED + k); training seeds only (not 5000 .. "
                        "109999, the validation and test goals)")
    p.add_argument("--force", action="store_true", help="replace an existing dataset")
    p.add_argument("--defaults", action="store_true",
                   help="write every default dataset (expert, scripted, loop-plan, random of "
                        "the goal tasks; see docs/datasets.md)")
    p.add_argument("--torch-threads", type=int, default=1, help="1 .. 256")
    add_ray_options(p)
    ns = p.parse_args(argv)
    return CollectSettings(**{f.name: getattr(ns, f.name)
                              for f in dataclasses.fields(CollectSettings)})


def check_job(source: CollectSource, n_episodes: int, seed: int, dataset_id: str,
              force: bool) -> None:
    """Every check of one dataset before any episode: the env id, the dataset id and its
    existence, the seeds, the policy (built once: the model is loaded and checked against
    the env)."""
    from agents.runs.loading import ModelPolicy

    task_targets(source.env)
    check_dataset_id(dataset_id, source.env)
    check_seeds(seed, n_episodes)
    if dataset_dir(dataset_id).exists() and not force:
        raise UserError(f"dataset {dataset_id} exists ({dataset_dir(dataset_id)}); pass "
                        "--force to replace it")
    policy, env_id, kwargs, wrapper, _ = build_source(source)
    env = make_env(env_id, kwargs, wrapper)
    try:
        if isinstance(policy, ModelPolicy):
            policy.check_env(env)
    finally:
        env.close()


def collect(source: CollectSource, n_episodes: int, seed: int, dataset_id: str,
            force: bool = False, options: RayOptions = SERIAL) -> Any:
    """Record ``n_episodes`` episodes from ``reset(seed=seed + k)`` and write them as the
    dataset ``dataset_id`` (:func:`write_dataset`); returns the loaded dataset."""
    policy, env_id, kwargs, wrapper, algorithm = build_source(source)
    seeds = goal_seeds(seed, n_episodes)
    t0 = time.time()
    episodes = collect_episodes(source, seeds, options)
    wall = time.time() - t0
    env = make_env(env_id, kwargs, wrapper)
    try:
        extra = dataset_metadata(source, policy, env, kwargs, wrapper, seeds, wall)
        return write_dataset(dataset_id, episodes, env, algorithm,
                             describe(source, algorithm, n_episodes), extra, force)
    finally:
        env.close()


def main(argv: Sequence[str] | None = None) -> list[Any]:
    """CLI entry point; returns the written datasets."""
    args = parse_args(argv)
    jobs = args.jobs()
    ids = [j[2] for j in jobs]
    if len(set(ids)) != len(ids):
        raise UserError("two datasets with one id")
    for source, n, dataset_id in jobs:
        check_job(source, n, args.seed, dataset_id, args.force)
    out = []
    t_all = time.time()
    for source, n, dataset_id in jobs:
        t0 = time.time()
        dataset = collect(source, n, args.seed, dataset_id, args.force, args.sharding)
        out.append(dataset)
        print(f"wrote {dataset_id}: {dataset.total_episodes} episodes, {dataset.total_steps} "
              f"steps, success {dataset.storage.metadata['success_rate']:.1%}, "
              f"{time.time() - t0:.1f} s ({dataset_dir(dataset_id)})", flush=True)
    if len(jobs) > 1:
        print(f"{len(jobs)} datasets in {time.time() - t_all:.1f} s")
    return out


if __name__ == "__main__":
    run_cli(main)
