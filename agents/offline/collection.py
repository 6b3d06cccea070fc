"""Offline datasets in Minari's format: what ``agents.collect`` writes and ``agents.bc`` reads.

* names: :func:`task_slug`, :func:`check_dataset_id` (``softhand/<task>/<kind>-v<N>``),
  :func:`dataset_dir` (``$MINARI_DATASETS_PATH/<id>``), :func:`check_seeds` (training seeds
  only), :data:`DEFAULT_DATASETS`;
* episodes: :class:`CollectSource` (a ``--policy`` choice in plain data), :func:`build_source`,
  :class:`UniformRandomPolicy`, :func:`record_episode` (every step of one episode),
  :func:`collect_chunk` / :func:`collect_episodes` (serial or over Ray workers,
  :mod:`agents.play.sharding`);
* writing: :func:`dataset_metadata`, :func:`write_dataset` (Minari's HDF5 storage).

The dataset's contents are described in ``agents.collect`` and ``docs/datasets.md``.
"""

from __future__ import annotations

import shutil
import subprocess
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.cli import UserError
from agents.common.env_factory import make_env, task_targets
from agents.common.metrics import success_kwargs
from agents.play.choice import SCRIPTED, PolicyChoice, build
from agents.play.sharding import (
    RayOptions,
    map_chunks,
    merge,
    split,
    worker_count,
)
from agents.play.test_scores import TEST_FAMILY_SIZE, TEST_SEED, VALIDATION_SEED

#: ``--policy`` value of the uniform random policy.
RANDOM = "random"
#: Namespace of the datasets: ids are ``softhand/<task>/<kind>-v<N>`` (:func:`task_slug`).
NAMESPACE = "softhand"
#: Author field of the datasets (the package's authors, as the docs name them).
AUTHOR = "softhand-env contributors"
#: Minari storage format.
DATA_FORMAT = "hdf5"
#: Per-step info entries recorded (``goal`` on the goal tasks only). ``termination_reason``
#: is stored as a string, ``""`` while the episode runs; ``object_velocity`` (vx, vy, omega;
#: m/s, m/s, rad/s) is read from the env's physics, the others from ``info``.
INFO_KEYS = ("object_pose", "object_velocity", "goal", "deformation", "setpoint",
             "friction_ratio", "contact_impulse", "grasped", "is_success", "termination_reason")
#: Episode metadata of the drawn hand and object parameters: ``param_<field>`` for these
#: fields of :class:`softhand_env.physics.params.HandParams` (SI; the nominal values without
#: randomisation), besides ``setpoint_latency`` (control steps).
PARAM_FIELDS = ("W_obj", "M_obj", "I_obj", "E", "c_n", "c_t", "Kp", "Kd", "Ki", "mu")
#: Held-out seed ranges ``[low, high)`` no dataset may use: the validation and test goals.
HELD_OUT = (("validation", VALIDATION_SEED, TEST_SEED),
            ("test", TEST_SEED, TEST_SEED + TEST_FAMILY_SIZE))
#: Serial collection (no Ray).
SERIAL = RayOptions()
#: Most episodes of one dataset.
MAX_EPISODES = 100_000


@dataclass(frozen=True)
class DefaultDataset:
    """One dataset of ``--defaults``: env id, kind (the id's ``<kind>``), ``--policy``,
    episodes."""

    env: str
    kind: str
    policy: str
    episodes: int

    @property
    def dataset_id(self) -> str:
        """``softhand/<task>/<kind>-v0``."""
        return f"{NAMESPACE}/{task_slug(self.env)}/{self.kind}-v0"


#: The default datasets of the goal tasks: ``expert`` (the shipped agent), ``scripted`` (the
#: model-based baseline), ``loop-plan`` (the rolling plan, Pose) and ``random``.
DEFAULT_DATASETS = (
    DefaultDataset("SoftHandTranslate-v0", "expert", "SoftHandTranslate-v0", 500),
    DefaultDataset("SoftHandTranslate-v0", "scripted", "model-based", 500),
    DefaultDataset("SoftHandTranslate-v0", "random", RANDOM, 1000),
    DefaultDataset("SoftHandReorient-v0", "expert", "SoftHandReorient-v0", 500),
    DefaultDataset("SoftHandReorient-v0", "scripted", "model-based", 500),
    DefaultDataset("SoftHandReorient-v0", "random", RANDOM, 1000),
    DefaultDataset("SoftHandPose-v0", "expert", "SoftHandPose-v0", 1000),
    DefaultDataset("SoftHandPose-v0", "scripted", "model-based", 500),
    DefaultDataset("SoftHandPose-v0", "loop-plan", "loop-plan", 500),
    DefaultDataset("SoftHandPose-v0", "random", RANDOM, 1000),
)


# ------------------------------------------------------------------------------ names, seeds
def task_slug(env_id: str) -> str:
    """The ``<task>`` part of a dataset id for a soft-hand env id: the name after
    ``SoftHand`` in lower case, ``Random`` as ``-random``, a version other than 0 appended
    (``SoftHandPose-v0`` -> ``pose``, ``SoftHandPoseRandom-v0`` -> ``pose-random``,
    ``SoftHandPose-v1`` -> ``pose-v1``, ``SoftHand-v0`` -> ``hand``)."""
    task_targets(env_id)  # a registered soft-hand id
    name, _, version = env_id.partition("-v")
    base = name[len("SoftHand"):]
    random = base.endswith("Random")
    base = (base[: -len("Random")] if random else base).lower() or "hand"
    return base + ("-random" if random else "") + ("" if version == "0" else f"-v{version}")


def check_dataset_id(dataset_id: str, env_id: str) -> None:
    """:class:`UserError` unless ``dataset_id`` is ``softhand/<task>/<kind>-v<N>`` with the
    ``<task>`` of ``env_id`` (:func:`task_slug`) and a Minari-valid name."""
    from minari.dataset.minari_dataset import parse_dataset_id

    want = f"{NAMESPACE}/{task_slug(env_id)}/"
    try:
        namespace, name, _ = parse_dataset_id(dataset_id)
    except ValueError:
        raise UserError(f"--dataset-id {dataset_id!r} is not a Minari dataset id "
                        f"({want}<kind>-v<N>, e.g. {want}expert-v0)") from None
    if f"{namespace}/" != want or "/" in name:
        raise UserError(f"--dataset-id {dataset_id!r}: datasets of {env_id} are named "
                        f"{want}<kind>-v<N> (e.g. {want}expert-v0)")


def dataset_dir(dataset_id: str | None) -> Path:
    """The local directory of a dataset id (``$MINARI_DATASETS_PATH/<id>``; None: the root,
    by default ``~/.minari/datasets``)."""
    from minari.storage.datasets_root_dir import get_dataset_path

    return Path(get_dataset_path(dataset_id))


def check_seeds(seed: int, n_episodes: int) -> None:
    """:class:`UserError` if the seeds ``seed`` to ``seed + n_episodes - 1`` meet a held-out
    family (:data:`HELD_OUT`)."""
    for name, low, high in HELD_OUT:
        if seed < high and seed + n_episodes > low:
            raise UserError(f"--seed {seed} with {n_episodes} episodes meets the {name} goals "
                            f"(seeds {low} .. {high - 1}); datasets use training seeds (e.g. "
                            f"--seed 0 with at most {VALIDATION_SEED} episodes, or --seed "
                            f">= {HELD_OUT[-1][2]})")


# ------------------------------------------------------------------------------ policies
class UniformRandomPolicy:
    """Uniform actions in ``action_space`` (the scripted policies' ``predict`` API); the
    samples of an episode come from the action space seeded with the episode's seed
    (:meth:`seed_episode`), so an episode depends on its seed only."""

    def __init__(self, action_space: Any):
        self.action_space = action_space

    def seed_episode(self, seed: int) -> None:
        """Seed the action samples of the next episode."""
        self.action_space.seed(int(seed))

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        """One uniform sample (shape of the action space)."""
        return np.asarray(self.action_space.sample()), None


@dataclass(frozen=True)
class CollectSource:
    """The policy and env of a collection in plain data (sent to Ray workers): ``policy`` as
    ``--policy`` takes it, ``env`` the env id, torch threads of a model."""

    policy: str
    env: str
    torch_threads: int = 1

    def choice(self) -> PolicyChoice | None:
        """The :class:`~agents.play.choice.PolicyChoice` of a model or scripted policy (None:
        :data:`RANDOM`)."""
        if self.policy == RANDOM:
            return None
        if self.policy in SCRIPTED:
            return PolicyChoice(policy=self.policy, env=self.env)
        return PolicyChoice(model=self.policy, env=self.env)


def build_source(source: CollectSource) -> tuple[Any, str, dict[str, Any], Any, str]:
    """Policy, env id, ``gym.make`` keywords, wrappers and algorithm name of a source
    (:func:`agents.play.choice.build`; ``random``: the id's own keywords with the benchmark's
    success tolerance, no wrapper)."""
    choice = source.choice()
    if choice is None:
        kwargs = dict(success_kwargs(source.env))
        probe = make_env(source.env, kwargs)
        policy = UniformRandomPolicy(probe.action_space)
        probe.close()
        return policy, source.env, kwargs, None, RANDOM
    if choice.model is not None:
        import torch

        torch.set_num_threads(source.torch_threads)
    policy, env_id, kwargs, wrapper, name = build(choice)
    if choice.policy is not None:
        name = choice.policy
    return policy, env_id, kwargs, wrapper, name


# ------------------------------------------------------------------------------ episodes
def _stack(items: Sequence[Any]) -> Any:
    """A list of equal-shaped entries (arrays, or dicts of them) as one array per leaf."""
    if isinstance(items[0], dict):
        return {k: _stack([it[k] for it in items]) for k in items[0]}
    return np.asarray(np.stack([np.asarray(it) for it in items]))


def _info_entry(info: dict[str, Any], keys: Sequence[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key in keys:
        value = info[key]
        if key == "termination_reason":
            out[key] = "" if value is None else str(value)
        elif isinstance(value, (bool, np.bool_)):
            out[key] = np.bool_(value)
        else:
            out[key] = np.asarray(value, dtype=np.float64)
    return out


def _with_physics(env: Any, info: dict[str, Any]) -> dict[str, Any]:
    """``info`` with the object velocity of the env's physics (a copy, shape (3,))."""
    return {**info, "object_velocity": np.array(env.unwrapped.physics.object_velocity,
                                                dtype=np.float64).reshape(3)}


def episode_params(env: Any, info: dict[str, Any]) -> dict[str, Any]:
    """The episode's drawn parameters after ``reset``: ``param_<field>`` of
    :data:`PARAM_FIELDS` (SI) and ``setpoint_latency`` (control steps)."""
    params = env.unwrapped.physics.params
    out: dict[str, Any] = {f"param_{f}": float(getattr(params, f)) for f in PARAM_FIELDS}
    out["setpoint_latency"] = int(info.get("setpoint_latency", 0))
    return out


def record_episode(env: Any, policy: Any, seed: int) -> dict[str, Any]:
    """Play one episode from ``reset(seed=seed)`` deterministically and return every step:
    ``observations`` (T + 1, ...), ``actions`` (T, ...; cast to the action space's dtype
    before ``step``, so that the stored actions replay the episode exactly), ``rewards``,
    ``terminations``, ``truncations`` (T,), ``infos`` ({key: (T + 1, ...)}, :data:`INFO_KEYS`
    present in the env's info), ``seed``, ``success`` and ``termination_reason`` of the last
    step (None: truncated) and ``params`` (:func:`episode_params`)."""
    if isinstance(policy, UniformRandomPolicy):
        policy.seed_episode(seed)
    obs, info = env.reset(seed=int(seed))
    params = episode_params(env, info)
    info = _with_physics(env, info)
    keys = [k for k in INFO_KEYS if k in info]
    space = env.action_space
    observations, infos = [obs], [_info_entry(info, keys)]
    actions, rewards, terms, truncs = [], [], [], []
    state, start = None, np.array([True])
    while True:
        action, state = policy.predict(obs, state, start, True)
        start = np.array([False])
        action = np.asarray(action, dtype=space.dtype).reshape(space.shape)
        obs, reward, terminated, truncated, info = env.step(action)
        info = _with_physics(env, info)
        observations.append(obs)
        infos.append(_info_entry(info, keys))
        actions.append(action)
        rewards.append(float(reward))
        terms.append(bool(terminated))
        truncs.append(bool(truncated))
        if terminated or truncated:
            break
    return {
        "seed": int(seed),
        "observations": _stack(observations),
        "actions": _stack(actions),
        "rewards": np.asarray(rewards, dtype=np.float64),
        "terminations": np.asarray(terms, dtype=bool),
        "truncations": np.asarray(truncs, dtype=bool),
        "infos": {k: ([e[k] for e in infos] if k == "termination_reason"
                      else _stack([e[k] for e in infos])) for k in keys},
        "success": bool(info["is_success"]),
        "termination_reason": info.get("termination_reason"),
        "params": params,
    }


@dataclass(frozen=True)
class CollectChunk:
    """Episodes a worker records on its own: the source and the seeds."""

    source: CollectSource
    seeds: tuple[int, ...]


def collect_chunk(chunk: CollectChunk) -> list[dict[str, Any]]:
    """:func:`record_episode` for every seed of a chunk, in a policy and env built here."""
    policy, env_id, kwargs, wrapper, _ = build_source(chunk.source)
    env = make_env(env_id, kwargs, wrapper)
    try:
        return [record_episode(env, policy, s) for s in chunk.seeds]
    finally:
        env.close()


def collect_episodes(source: CollectSource, seeds: Sequence[int],
                     options: RayOptions = SERIAL) -> list[dict[str, Any]]:
    """The episodes of ``seeds`` in seed order, serially or split over Ray workers
    (``options``; the same episodes either way)."""
    n_chunks = worker_count(options, len(seeds))
    chunks = [CollectChunk(source, tuple(int(s) for s in part)) for part in split(seeds, n_chunks)]
    return merge(map_chunks(collect_chunk, chunks, options.address, options.workers))


# ------------------------------------------------------------------------------ metadata
def code_permalink() -> str:
    """Where the collecting code is: the package and its version, plus the git commit when
    the package runs from a checkout (``+dirty`` with uncommitted changes)."""
    from agents.runs.hyperparams import versions

    text = f"softhand-env=={versions()['softhand-env']} (agents/collect.py)"
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], check=True,
                                capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no"], check=True, capture_output=True,
                               text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return text
    return f"{text}, git {commit}{'+dirty' if dirty else ''}"


def recorded_test_success(policy: Any) -> dict[str, Any] | None:
    """The policy's success on the test goals where one is recorded: a shipped model's
    ``results.yml`` (seeded from 10000, the benchmark), else a run's last
    ``test_scores.yml`` entry; None for a scripted or random policy or an unscored run."""
    from agents.play.test_scores import is_shipped, read_scores
    from agents.runs.loading import ModelPolicy

    if not isinstance(policy, ModelPolicy):
        return None
    run_dir = policy.run.run_dir
    if is_shipped(run_dir):
        from softhand_env.physics.safe_yaml import read_bounded

        path = run_dir / "results.yml"
        if not path.is_file():
            return None
        import yaml

        data = yaml.safe_load(read_bounded(path))
        if data.get("seed") != TEST_SEED or data.get("goals_file") is not None:
            return None
        summary = data["summary"]
        return {"n_episodes": int(summary["n_episodes"]), "first_seed": TEST_SEED,
                "success": float(summary["success_rate"]), "source": "results.yml"}
    scores = read_scores(run_dir)["scores"]
    if not scores:
        return None
    last = scores[-1]
    return {"n_episodes": int(last["n_episodes"]), "first_seed": int(last["first_seed"]),
            "success": float(last["success"]), "source": "test_scores.yml"}


def dataset_metadata(source: CollectSource, policy: Any, env: Any, kwargs: dict[str, Any],
                     wrapper: Any, seeds: Sequence[int], wall_time_s: float) -> dict[str, Any]:
    """The dataset's own metadata keys (beside Minari's): ``policy`` (the ``--policy``
    value, and a model's file), ``test_success`` (:func:`recorded_test_success`), ``env_id`` and
    ``env_version`` (the id's ``-v<N>``), ``env_signature``
    (:func:`softhand_env.envs.signature.env_signature`: sensor model, observation layout,
    action mapping, control period, package version), ``sensor_model``, the ``gym.make``
    keywords and wrappers, ``seeds`` (first and count), ``info_keys``, the episodes'
    success rate and ``collection_wall_time_s``."""
    from agents.runs.loading import ModelPolicy
    from softhand_env.envs.signature import env_signature

    signature = env_signature(env)
    return {
        "policy": source.policy,
        "policy_file": str(policy.path) if isinstance(policy, ModelPolicy) else None,
        "test_success": recorded_test_success(policy),
        "env_id": source.env,
        "env_version": int(source.env.rpartition("-v")[2]),
        "env_signature": signature,
        "sensor_model": signature.get("sensor_model", "ideal"),
        "env_kwargs": dict(kwargs),
        "env_wrapper": wrapper,
        "first_seed": int(seeds[0]),
        "n_seeds": len(seeds),
        "info_keys": [k for k in INFO_KEYS],
        "collection_wall_time_s": round(float(wall_time_s), 1),
    }


# ------------------------------------------------------------------------------ writing
def write_dataset(dataset_id: str, episodes: Sequence[dict[str, Any]], env: Any,
                  algorithm: str, description: str, extra: dict[str, Any],
                  force: bool = False) -> Any:
    """Write ``episodes`` (:func:`record_episode` records) as the Minari dataset
    ``dataset_id`` with the spaces and spec of ``env`` (also the ``eval_env_spec``) and the
    metadata ``extra`` (plus the episodes' success rate); an existing dataset is replaced
    only with ``force``. Returns the :class:`minari.MinariDataset`."""
    import minari
    from minari.data_collector.episode_buffer import EpisodeBuffer

    from softhand_env import __version__

    path = dataset_dir(dataset_id)
    if path.exists():
        if not force:
            raise UserError(f"dataset {dataset_id} exists ({path}); pass --force to replace it")
        shutil.rmtree(path)
    buffers = [EpisodeBuffer(id=k, seed=ep["seed"], observations=ep["observations"],
                             actions=ep["actions"], rewards=ep["rewards"],
                             terminations=ep["terminations"], truncations=ep["truncations"],
                             infos=ep["infos"])
               for k, ep in enumerate(episodes)]
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*author_email.*")
        dataset = minari.create_dataset_from_buffers(
            dataset_id=dataset_id, buffer=buffers, env=env, eval_env=env.spec,
            algorithm_name=algorithm, author=AUTHOR, code_permalink=code_permalink(),
            description=description, data_format=DATA_FORMAT,
            requirements=[f"softhand-env=={__version__}"])
    success = [ep["success"] for ep in episodes]
    dataset.storage.update_metadata({**extra, "success_rate": float(np.mean(success))})
    dataset.storage.update_episode_metadata(
        [{"success": bool(ep["success"]), "termination_reason": ep["termination_reason"] or "",
          **ep["params"]} for ep in episodes])
    return minari.load_dataset(dataset_id)


def describe(source: CollectSource, algorithm: str, n: int) -> str:
    """The dataset's ``description``."""
    who = {RANDOM: "uniform random actions"}.get(source.policy, f"policy {source.policy}")
    return (f"{n} episodes of {source.env} ({who}; algorithm {algorithm}) from "
            "python -m agents.collect: blind observations, actions, rewards, terminations, "
            "truncations and per-step privileged infos (object pose, goal, deformations, "
            "friction ratio, termination reason).")
