"""The training library of ``agents.train`` and ``agents.distill``: settings, run config, build.

* :func:`make_parser` and :class:`TrainSettings` (``TrainSettings.from_namespace``: the
  range-checked settings of a parsed command line);
* :func:`resolve_config`: the :class:`~agents.runs.records.RunConfig` of the settings (the
  hyper-parameter entry merged with the overrides, and the record);
* :func:`build`: the algorithm on its training envs and the validation env, every
  hyper-parameter checked before a run directory exists;
* :func:`probe_signature`: the env signature of the run, its first reset (the grasp phase)
  tried before a run directory exists;
* :func:`start_from`: weights and statistics of a saved model as the starting point;
* :func:`next_run_dir`: the run directory, numbered as ``rl_zoo3.train`` numbers its runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, TypeVar

from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

from agents.common.cli import SEED_MAX, ArgumentParser, UserError, check_range, parse_kv
from agents.common.env_factory import check_env_id, goal_seeds, make_env, make_vec_env
from agents.common.metrics import success_kwargs
from agents.runs.hyperparams import (
    ALGOS,
    algo_class,
    algo_kwargs,
    config_path,
    load_hyperparams,
    normalize_kwargs,
    versions,
)
from agents.runs.records import EvalSettings, RunConfig, RunRecord
from agents.sb3 import policies  # noqa: F401  (registers AsymmetricPolicy / BlindActorPolicy)
from agents.sb3.native_vec_env import SB3_VEC_ENVS, NativeVecEnv, make_sb3_vec_env

_Settings = TypeVar("_Settings", bound="TrainSettings")

#: First paragraph of the training CLI's help.
DESCRIPTION = "Train a Stable-Baselines3 agent on a soft-hand task (a thin CLI, RL-Zoo style)."


def make_parser(prog: str = "python -m agents.train", description: str | None = None
                ) -> ArgumentParser:
    """The training CLI's parser (``agents.distill`` adds its options to it)."""
    p = ArgumentParser(prog=prog, description=description or DESCRIPTION)
    p.add_argument("--env", required=True, help="environment id, e.g. SoftHandTranslate-v0")
    p.add_argument("--algo", default="ppo", choices=sorted(ALGOS))
    p.add_argument("--conf-file", default=None,
                   help="hyper-parameter YAML in RL Zoo's dialect (default: the installed "
                        "agents/configs/<algo>.yml)")
    p.add_argument("--seed", type=int, default=0, help="seed, 0 .. 2**32 - 1")
    p.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY:VALUE",
                   help="override env_kwargs of the entry (values parsed as YAML)")
    p.add_argument("--hyperparams", nargs="*", default=[], metavar="KEY:VALUE",
                   help="override algorithm keys of the entry (values parsed as YAML)")
    p.add_argument("--n-timesteps", type=int, default=None, help="override n_timesteps (>= 1)")
    p.add_argument("--log-folder", default="logs")
    p.add_argument("--run-name", default=None,
                   help="run directory name (default <env>_<k>, k = latest + 1 as in RL Zoo)")
    p.add_argument("--vec-env", default=None, choices=SB3_VEC_ENVS,
                   help="vectorisation (default: the entry's vec_env key, else dummy); native = "
                        "the batched SoftHandVectorEnv through agents.sb3.native_vec_env")
    p.add_argument("--eval-freq", type=int, default=50_000,
                   help="evaluate every this many env steps (<= 0: never)")
    p.add_argument("--eval-episodes", type=int, default=20, help="validation goals, 1 .. 10000")
    p.add_argument("--eval-seed", type=int, default=5000, help="seed of the validation goals")
    p.add_argument("--trained-agent", default=None,
                   help="start from a saved model (run directory, zip or shipped name): its "
                        "weights and observation statistics; the env id may differ (e.g. the "
                        "Random id of the same task) if the spaces match")
    p.add_argument("--stop-success", type=float, default=None,
                   help="stop once the validation success rate reaches this, in (0, 1]")
    p.add_argument("--save-freq", type=int, default=250_000,
                   help="checkpoint every this many env steps (<= 0: never)")
    p.add_argument("--device", default="cpu", choices=("cpu", "cuda", "auto"))
    p.add_argument("--torch-threads", type=int, default=1, help="torch threads, 1 .. 256")
    p.add_argument("--fit-threads", type=int, default=None,
                   help="torch threads while the networks are fitted between rollouts (the "
                        "physics is idle then), 1 .. 256 (default: --torch-threads)")
    p.add_argument("--no-progress-bar", action="store_true")
    p.add_argument("--verbose", type=int, default=1, choices=(0, 1, 2))
    return p


@dataclass
class TrainSettings:
    """The training command line (``python -m agents.train --help``), range-checked.

    Steps and frequencies are env steps; seeds 0 .. 2**32 - 1; ``env_kwargs`` and
    ``hyperparams`` are the ``KEY:VALUE`` overrides as given.
    """

    env: str
    algo: str = "ppo"
    conf_file: str | None = None
    seed: int = 0
    env_kwargs: list[str] = dataclasses.field(default_factory=list)
    hyperparams: list[str] = dataclasses.field(default_factory=list)
    n_timesteps: int | None = None
    log_folder: str = "logs"
    run_name: str | None = None
    vec_env: str | None = None
    eval_freq: int = 50_000
    eval_episodes: int = 20
    eval_seed: int = 5000
    trained_agent: str | None = None
    stop_success: float | None = None
    save_freq: int = 250_000
    device: str = "cpu"
    torch_threads: int = 1
    fit_threads: int | None = None
    no_progress_bar: bool = False
    verbose: int = 1

    def __post_init__(self) -> None:
        """Range checks (UserError on a bad value)."""
        check_range("--seed", self.seed, 0, SEED_MAX)
        check_range("--eval-seed", self.eval_seed, 0, SEED_MAX - 10_000)
        check_range("--eval-episodes", self.eval_episodes, 1, 10_000)
        check_range("--torch-threads", self.torch_threads, 1, 256)
        if self.fit_threads is not None:
            check_range("--fit-threads", self.fit_threads, 1, 256)
        if self.stop_success is not None and not 0.0 < self.stop_success <= 1.0:
            raise UserError(f"--stop-success must be in (0, 1] (got {self.stop_success!r})")
        if self.n_timesteps is not None:
            check_range("--n-timesteps", self.n_timesteps, 1, 10**10)
        if self.run_name is not None and (not self.run_name or Path(self.run_name).name
                                          != self.run_name or self.run_name in (".", "..")):
            raise UserError(f"--run-name must be one directory name (got {self.run_name!r})")
        log_folder = Path(self.log_folder)
        if log_folder.exists() and not log_folder.is_dir():
            raise UserError(f"--log-folder {log_folder} exists and is not a directory")

    @classmethod
    def from_namespace(cls: type[_Settings], ns: argparse.Namespace) -> _Settings:
        """The settings of a parsed command line (every field of the class, by name)."""
        return cls(**{f.name: getattr(ns, f.name) for f in dataclasses.fields(cls)})


def next_run_dir(log_folder: Path, algo: str, env_id: str, name: str | None) -> Path:
    """``<log_folder>/<algo>/<name>``, or ``<env_id>_<k>`` with k = latest run id + 1, as
    ``rl_zoo3.train`` numbers its runs (so both can share a log folder)."""
    base = log_folder / algo
    if name is not None:
        return base / name
    ids = [int(p.name.rpartition("_")[2]) for p in base.glob(f"{env_id}_*")
           if p.is_dir() and p.name.rpartition("_")[2].isdigit()
           and p.name.rpartition("_")[0] == env_id]
    return base / f"{env_id}_{max(ids, default=0) + 1}"


def resolve_config(args: TrainSettings, command: str = "agents.train") -> RunConfig:
    """The run config: ``hyperparams`` (YAML entry merged with the CLI overrides, the zoo's
    dialect) and ``record`` (everything else we save with the run)."""
    check_env_id(args.env)
    hp = load_hyperparams(args.algo, args.env, args.conf_file)
    env_over = parse_kv(args.env_kwargs, "--env-kwargs")
    hp_over = parse_kv(args.hyperparams, "--hyperparams")
    hp.update(hp_over)
    if not isinstance(hp["env_kwargs"], dict):
        raise UserError("env_kwargs must be a mapping")
    hp["env_kwargs"] = {**hp["env_kwargs"], **env_over}
    if args.n_timesteps is not None:
        hp["n_timesteps"] = args.n_timesteps
    vec_env = args.vec_env or hp.pop("vec_env", "dummy")
    hp.pop("vec_env", None)
    if vec_env not in SB3_VEC_ENVS:
        raise UserError(f"vec_env must be one of {SB3_VEC_ENVS} (got {vec_env!r})")
    for key, low in (("n_envs", 1), ("n_timesteps", 1)):
        value = hp[key]
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= 10**10:
            raise UserError(f"{key} must be an int in [{low}, 1e10] (got {value!r})")
    if hp["n_envs"] > 1024:
        raise UserError(f"n_envs must be <= 1024 (got {hp['n_envs']})")
    record = RunRecord(
        algo=args.algo,
        env_id=args.env,
        seed=args.seed,
        conf_file=str(config_path(args.algo, args.conf_file)),
        overrides={"env_kwargs": env_over, "hyperparams": hp_over,
                   "n_timesteps": args.n_timesteps},
        save_freq=args.save_freq,
        eval=EvalSettings(eval_freq=args.eval_freq, n_eval_episodes=args.eval_episodes,
                          eval_seed=args.eval_seed, success_kwargs=success_kwargs(args.env),
                          stop_success=args.stop_success),
        device=args.device,
        torch_threads=args.torch_threads,
        fit_threads=args.torch_threads if args.fit_threads is None else args.fit_threads,
        trained_agent=None,  # the start model's provenance (start_from), if any
        vec_env=vec_env,
        versions=versions(),
        command=f"python -m {command} " + shlex.join(sys.argv[1:]),
        started=datetime.now(timezone.utc).isoformat(timespec="seconds"),
    )
    return RunConfig(hyperparams=hp, record=record)


#: VecNormalize keywords a run config may set, and those that must be finite and > 0 (the
#: rule the loader applies to saved statistics, :mod:`agents.runs.normalization`).
NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon",
                  "norm_obs_keys")
_POSITIVE = ("clip_obs", "clip_reward", "epsilon")


def check_normalize(norm: dict[str, Any]) -> None:
    """:class:`UserError` for a ``normalize`` mapping a saved run could not be loaded with:
    an unknown key, ``clip_obs`` / ``clip_reward`` / ``epsilon`` not a finite number > 0,
    ``gamma`` not in [0, 1], ``norm_obs`` / ``norm_reward`` not a bool."""
    import math

    unknown = sorted(str(k)[:40] for k in norm if k not in NORMALIZE_KEYS)
    if unknown:
        raise UserError(f"normalize: unknown key(s) {', '.join(unknown)} (known: "
                        f"{', '.join(NORMALIZE_KEYS)})")
    for key in _POSITIVE:
        if key in norm:
            v = norm[key]
            if (isinstance(v, bool) or not isinstance(v, (int, float))
                    or not math.isfinite(v) or v <= 0):
                raise UserError(f"normalize: {key} must be a finite number > 0 "
                                f"(got {str(v)[:40]})")
    if "gamma" in norm:
        g = norm["gamma"]
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not 0 <= g <= 1:
            raise UserError(f"normalize: gamma must be a number in [0, 1] (got {str(g)[:40]})")
    for key in ("norm_obs", "norm_reward"):
        if key in norm and not isinstance(norm[key], bool):
            raise UserError(f"normalize: {key} must be true or false (got {str(norm[key])[:40]})")


def make_validation_env(env_id: str, env_kwargs: dict[str, Any], wrapper: Any, vec_env: str,
                        ev: EvalSettings) -> Any:
    """The SB3 ``VecEnv`` that plays the validation goals ``reset(seed=ev.eval_seed + k)``,
    k < ``ev.n_eval_episodes``, with the benchmark's success rule (``ev.success_kwargs``).

    With the native vector env (``vec_env="native"``) one hand per goal, in one
    :class:`~agents.sb3.native_vec_env.NativeVecEnv` under the training env's vector
    wrappers (the same chain, which VecNormalize's statistics sync walks level by level);
    otherwise one monitored env that plays the goals in turn
    (:class:`~agents.common.env_factory.GoalSeeds`). Call :func:`rewind_validation` before
    each evaluation."""
    kwargs = {**env_kwargs, **ev.success_kwargs}
    if vec_env == "native":
        return make_sb3_vec_env(env_id, ev.n_eval_episodes, ev.eval_seed, kwargs, "native",
                                env_wrapper=wrapper)
    return make_vec_env(env_id, 1, kwargs, None,
                        seeds=goal_seeds(ev.eval_seed, ev.n_eval_episodes),
                        env_wrapper=wrapper)


def rewind_validation(eval_env: Any, eval_seed: int) -> None:
    """Make the next ``reset()`` of a :func:`make_validation_env` env start its goal set over
    (hand k of the native env seeded ``eval_seed + k``; the single env's
    :class:`~agents.common.env_factory.GoalSeeds` rewound), so that every evaluation plays the
    same goals."""
    if isinstance(eval_env.unwrapped, NativeVecEnv):
        eval_env.seed(eval_seed)
    else:
        eval_env.env_method("rewind")


def build(config: RunConfig, verbose: int = 1) -> tuple[Any, Any]:
    """The algorithm (on its training envs) and the validation env of a run config.

    Everything a hyper-parameter can break is built here, before the run directory exists;
    any failure is a :class:`UserError` naming the algorithm.
    """
    import torch

    hp, rec = config.hyperparams, config.record
    torch.set_num_threads(rec.torch_threads)
    set_random_seed(rec.seed)
    env_id, algo, seed = rec.env_id, rec.algo, rec.seed
    kwargs = algo_kwargs(algo, hp)
    norm = normalize_kwargs(config.normalize)
    if norm is not None:
        check_normalize(norm)
    wrapper = config.env_wrapper
    env = make_sb3_vec_env(env_id, config.n_envs, seed, config.env_kwargs, rec.vec_env,
                           env_wrapper=wrapper)
    eval_env = make_validation_env(env_id, config.env_kwargs, wrapper, rec.vec_env, rec.eval)
    try:
        if norm is not None:
            norm_kw = {"gamma": kwargs.get("gamma", 0.99), **norm}
            env = VecNormalize(env, **norm_kw)
            eval_env = VecNormalize(eval_env, **{**norm_kw, "training": False,
                                                 "norm_reward": False})
        model = algo_class(algo)(config.policy, env, seed=seed, device=rec.device,
                                 verbose=verbose, **kwargs)
    except Exception as exc:  # SB3 raises ValueError/TypeError/AssertionError/KeyError...
        env.close()
        eval_env.close()
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise UserError(f"cannot build {algo.upper()} from the hyper-parameters: {msg}") from None
    return model, eval_env


def probe_signature(env_id: str, env_kwargs: dict[str, Any], env_wrapper: Any, seed: int
                    ) -> dict[str, Any]:
    """The env signature (:func:`softhand_env.envs.signature.env_signature`) of one env of
    the run, after one ``reset(seed=seed)``: a configuration whose grasp phase fails (e.g.
    ``hand_overrides: {Kd: 1e6}``) raises its ``PhysicsError`` here, before the run directory
    exists (one line and exit 2 in the CLIs), not at the first reset of training."""
    from softhand_env.envs.signature import env_signature

    probe = make_env(env_id, env_kwargs, env_wrapper)
    try:
        probe.reset(seed=seed)
        return env_signature(probe)
    finally:
        probe.close()


def start_from(model: Any, spec: str, record: RunRecord) -> None:
    """Load the weights and observation statistics of the saved model ``spec`` into ``model``
    (same algorithm and policy, same observation and action spaces; the env id may differ).
    The source's path, sha256, env id, steps and wall time go to ``record.trained_agent``.
    """
    from agents.runs.loading import ModelPolicy
    from agents.runs.model_files import sha256

    src = ModelPolicy(spec)
    if type(src.model) is not type(model) or type(src.model.policy) is not type(model.policy):
        raise UserError(f"--trained-agent {spec}: a {type(src.model.policy).__name__} of "
                        f"{src.algo}, not the run's {type(model.policy).__name__}")
    for name in ("observation_space", "action_space"):
        if getattr(src.model, name) != getattr(model, name):
            raise UserError(f"--trained-agent {spec}: its {name} differs from the run's")
    try:
        model.policy.load_state_dict(src.model.policy.state_dict())
    except RuntimeError as exc:  # other network sizes
        raise UserError(f"--trained-agent {spec}: weights do not fit the run's policy "
                        f"({' '.join(str(exc).split())[:200]})") from None
    vecnorm = model.get_vec_normalize_env()
    if (vecnorm is None) != (src.normalizer is None):
        raise UserError(f"--trained-agent {spec}: observation normalisation differs from the "
                        "run's (normalize)")
    if vecnorm is not None:
        src.normalizer.load_into(vecnorm)
    record.trained_agent = {
        "path": str(src.path), "sha256": sha256(src.path), "env_id": src.env_id,
        "total_timesteps": src.run.record.get("total_timesteps"),
        "wall_time_s": src.run.record.get("wall_time_s")}
