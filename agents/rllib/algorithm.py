"""The RLlib PPO algorithm on a soft-hand env (RLlib's new API stack: RLModule, Learner,
EnvRunner, ConnectorV2).

:func:`require_rllib` imports RLlib or raises a one-line
:class:`~agents.common.cli.UserError` with the install hint. :func:`build_algorithm` builds
PPO from :class:`~agents.rllib.settings.PPOSettings`: ``K`` env runners (Ray actors of one
CPU each; 0: sampling in this process) of ``M`` envs each, made by :func:`make_rllib_env` (our
:func:`~agents.common.env_factory.make_env`, so the entry's keywords and wrappers), a local
learner in this process, observations through RLlib's ``MeanStdFilter`` when the entry
normalises them. Ray must be initialised first (:func:`agents.play.sharding.cluster_cpus`).
:func:`train_until` runs training iterations until ``T`` env steps are sampled;
:func:`module_weights` and :func:`filter_state` are what :mod:`agents.rllib.export` writes.

The env runners import this module (RLlib sends :func:`make_rllib_env` by reference): on a
cluster every node needs the same package (the same checkout or the same installed version).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from agents.common.cli import UserError
from agents.rllib.settings import CLIP_OBS, PPOSettings

#: The install hint of the missing-RLlib error (the extra defined in pyproject.toml).
INSTALL_HINT = "pip install 'softhand-env[rllib]'"
#: Name of the env in Ray's registry (the id and keywords travel in the env config).
ENV_NAME = "softhand"
#: The RLModule id of a single-agent algorithm.
MODULE_ID = "default_policy"
#: Torch threads of the learner and of each env runner (one CPU each; torch's default of one
#: thread per core made inference and updates ~10x slower on a shared 2-core machine).
TORCH_THREADS = 1


def require_rllib(flag: str = "agents.rllib_train") -> Any:
    """``ray.rllib``, or :class:`UserError` (one line, the install hint) if Ray or RLlib's
    dependencies are missing."""
    try:
        import ray.rllib
        from ray.rllib.algorithms.ppo import PPOConfig  # noqa: F401  (imports torch, tree, ...)
    except ImportError as exc:
        raise UserError(f"{flag} needs Ray RLlib, which is not installed ({INSTALL_HINT}; "
                        f"{exc})") from None
    return ray.rllib


def make_rllib_env(config: Any) -> Any:
    """The env of an env runner: ``make_env(config["env_id"], config["env_kwargs"],
    config["env_wrapper"])`` (``config``: RLlib's ``EnvContext``, a dict)."""
    import torch

    from agents.common.env_factory import make_env

    torch.set_num_threads(TORCH_THREADS)  # runs in the env runner's process
    return make_env(config["env_id"], dict(config.get("env_kwargs") or {}),
                    config.get("env_wrapper"))


def _mean_std_filter(*args: Any, **kwargs: Any) -> Any:
    """The env-to-module connector: observations through a ``MeanStdFilter`` clipped at
    :data:`~agents.rllib.settings.CLIP_OBS` (VecNormalize's clip)."""
    from ray.rllib.connectors.env_to_module import MeanStdFilter

    return MeanStdFilter(clip_by_value=CLIP_OBS)


@dataclass(frozen=True)
class Sampling:
    """Where the env steps come from: ``num_env_runners`` Ray actors (0: this process) of
    ``envs_per_runner`` envs of ``env_id`` with ``env_kwargs`` / ``env_wrapper``; ``seed``
    seeds the runners' envs and the module's initial weights."""

    env_id: str
    env_kwargs: dict[str, Any]
    env_wrapper: Any
    num_env_runners: int
    envs_per_runner: int
    seed: int


def ppo_config(settings: PPOSettings, sampling: Sampling) -> Any:
    """RLlib's ``PPOConfig`` (new API stack, torch) of ``settings`` on ``sampling``."""
    require_rllib()
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.tune.registry import register_env

    register_env(ENV_NAME, make_rllib_env)
    config = (
        PPOConfig()
        .api_stack(enable_rl_module_and_learner=True, enable_env_runner_and_connector_v2=True)
        .framework("torch")
        .environment(ENV_NAME, env_config={"env_id": sampling.env_id,
                                           "env_kwargs": sampling.env_kwargs,
                                           "env_wrapper": sampling.env_wrapper},
                     normalize_actions=False, clip_actions=True)
        .env_runners(num_env_runners=sampling.num_env_runners,
                     num_envs_per_env_runner=sampling.envs_per_runner,
                     num_cpus_per_env_runner=1,
                     env_to_module_connector=_mean_std_filter if settings.norm_obs else None)
        .learners(num_learners=0)
        .training(**settings.training_kwargs())
        .rl_module(model_config=DefaultModelConfig(
            fcnet_hiddens=list(settings.hidden), fcnet_activation=settings.activation,
            head_fcnet_hiddens=[], vf_share_layers=False, free_log_std=True))
        .debugging(seed=sampling.seed, log_level="ERROR")
        .reporting(metrics_num_episodes_for_smoothing=20)
    )
    return config


def build_algorithm(settings: PPOSettings, sampling: Sampling) -> Any:
    """The PPO algorithm (its env runners started), the log std of every copy of the module set
    to ``settings.log_std_init``; torch in this process (the learner) on
    :data:`TORCH_THREADS` threads."""
    import torch

    torch.set_num_threads(TORCH_THREADS)
    algo = ppo_config(settings, sampling).build_algo()
    weights = algo.learner_group.get_weights()
    weights[MODULE_ID]["pi.log_std"][:] = settings.log_std_init
    algo.learner_group.set_weights(weights)
    algo.env_runner_group.sync_weights(from_worker_or_learner_group=algo.learner_group,
                                       inference_only=True)
    return algo


def sampled_steps(result: dict[str, Any]) -> int:
    """Env steps sampled since the start, from a result of ``algo.train()``."""
    from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME

    return int(result[ENV_RUNNER_RESULTS].get(NUM_ENV_STEPS_SAMPLED_LIFETIME, 0))


@dataclass
class TrainProgress:
    """Iterations run, env steps sampled (total) and wall time (s) of the ``train`` calls."""

    iterations: int = 0
    env_steps: int = 0
    wall_s: float = 0.0
    last_return: float | None = None


def train_until(algo: Any, stop_timesteps: int, progress: TrainProgress | None = None,
                report: Callable[[TrainProgress], None] | None = None) -> TrainProgress:
    """``algo.train()`` until at least ``stop_timesteps`` env steps are sampled in all (the last
    iteration completes: the count ends at a multiple of the train batch); ``report`` is
    called after every iteration."""
    from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, EPISODE_RETURN_MEAN

    progress = progress or TrainProgress()
    while progress.env_steps < stop_timesteps:
        t0 = time.perf_counter()
        result = algo.train()
        progress.wall_s += time.perf_counter() - t0
        progress.iterations += 1
        progress.env_steps = sampled_steps(result)
        ret = result[ENV_RUNNER_RESULTS].get(EPISODE_RETURN_MEAN)
        progress.last_return = None if ret is None else float(ret)
        if report is not None:
            report(progress)
    return progress


def module_weights(algo: Any) -> dict[str, Any]:
    """The learner's RLModule weights (name -> NumPy array; actor and critic)."""
    return dict(algo.learner_group.get_weights()[MODULE_ID])


def filter_state(algo: Any) -> dict[str, Any] | None:
    """State of the local env runner's ``MeanStdFilter`` (merged from every runner after each
    iteration), or None if observations are not filtered."""
    from ray.rllib.core import COMPONENT_ENV_TO_MODULE_CONNECTOR as CONNECTOR

    state = algo.env_runner.get_state(components=CONNECTOR)[CONNECTOR]
    return state.get("MeanStdFilter")
