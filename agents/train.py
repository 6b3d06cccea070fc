"""Train a Stable-Baselines3 agent on a soft-hand task (a thin CLI, RL-Zoo style).

Hyper-parameters come from ``softhand_env/configs/agents/<algo>.yml`` (a mapping keyed by env
id, see that file) and nowhere else; the CLI only picks the entry and applies overrides::

    python -m agents.train --algo ppo --env SoftHandTranslate-v0 --seed 0
    python -m agents.train --algo sac --env SoftHandReorient-v0 --n-timesteps 20000 \\
        --env-kwargs max_delta_deg:0.5 --hyperparams learning_rate:1e-3 --log-folder logs

The run directory ``<log-folder>/<algo>/<env_id>_<k>/`` is laid out as RL Zoo's (see
:mod:`agents.loading`): the final model ``<env_id>.zip``; ``<env_id>/config.yml`` (the YAML
entry + overrides as the zoo saves it, plus our record: seed, env signature, validation
results, package versions, command, wall time, sha256 of every model file),
``<env_id>/args.yml``, the observation statistics ``<env_id>/vecnormalize.npz`` (plain arrays)
and ``.pkl`` (for rl_zoo3); ``best_model.zip`` (best on the validation goals), checkpoints
``rl_model_<n>_steps.zip``, ``evaluations.npz`` and TensorBoard logs (``tb/``). Every argument
and hyper-parameter is checked (the algorithm and its envs are built) before the directory is
created. Evaluate it with ``python -m agents.evaluate --model <run dir>`` or
``python -m rl_zoo3.enjoy --gym-packages softhand_env -f <log-folder> --algo <algo> --env
<env_id> --exp-id <k>``.

Evaluation during training (:class:`HeldOutEvalCallback`) plays a fixed validation goal set
(``--eval-seed``, default 5000: episode k starts with ``reset(seed=5000 + k)``), disjoint from
the test goals of :mod:`agents.evaluate` (seed 10000), with the benchmark's success rule (1 mm /
1 deg at the episode's end) whatever the training tolerance; the best model is the one with
the highest success rate, ties broken by the lower median final error.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

from agents import policies  # noqa: F401  (registers AsymmetricPolicy / BlindActorPolicy)
from agents.cli import SEED_MAX, ArgumentParser, UserError, check_range, parse_kv, run_cli
from agents.env_factory import (
    check_env_id,
    goal_seeds,
    make_env,
    make_vec_env,
    task_targets,
)
from agents.hyperparams import (
    ALGOS,
    algo_class,
    algo_kwargs,
    config_path,
    load_hyperparams,
    normalize_kwargs,
    versions,
)
from agents.loading import BEST_MODEL
from agents.metrics import error_score, final_errors, success_kwargs, summarize
from agents.native_vec_env import SB3_VEC_ENVS, make_sb3_vec_env, vector_wrappers
from agents.normalization import save_stats
from agents.run_layout import save_vecnormalize, write_args, write_run_config
from softhand_env.envs.signature import env_signature


def make_parser(prog: str = "python -m agents.train", description: str | None = None
                ) -> ArgumentParser:
    """The training CLI's parser (shared with :mod:`agents.distill`, which adds its options)."""
    p = ArgumentParser(prog=prog, description=description or __doc__.split("\n\n")[0])
    p.add_argument("--env", required=True, help="environment id, e.g. SoftHandTranslate-v0")
    p.add_argument("--algo", default="ppo", choices=sorted(ALGOS))
    p.add_argument("--conf-file", default=None,
                   help="hyper-parameter YAML in RL Zoo's dialect (default: the installed "
                        "softhand_env/configs/agents/<algo>.yml)")
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
                        "the batched SoftHandVectorEnv through agents.native_vec_env")
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
    p.add_argument("--no-progress-bar", action="store_true")
    p.add_argument("--verbose", type=int, default=1, choices=(0, 1, 2))
    return p


def check_args(args: argparse.Namespace) -> argparse.Namespace:
    """Range checks of the parsed training arguments (UserError on a bad value)."""
    check_range("--seed", args.seed, 0, SEED_MAX)
    check_range("--eval-seed", args.eval_seed, 0, SEED_MAX - 10_000)
    check_range("--eval-episodes", args.eval_episodes, 1, 10_000)
    check_range("--torch-threads", args.torch_threads, 1, 256)
    if args.stop_success is not None and not 0.0 < args.stop_success <= 1.0:
        raise UserError(f"--stop-success must be in (0, 1] (got {args.stop_success!r})")
    if args.n_timesteps is not None:
        check_range("--n-timesteps", args.n_timesteps, 1, 10**10)
    if args.run_name is not None and (not args.run_name or Path(args.run_name).name
                                      != args.run_name or args.run_name in (".", "..")):
        raise UserError(f"--run-name must be one directory name (got {args.run_name!r})")
    log_folder = Path(args.log_folder)
    if log_folder.exists() and not log_folder.is_dir():
        raise UserError(f"--log-folder {log_folder} exists and is not a directory")
    return args


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Command-line arguments (see ``python -m agents.train --help``), range-checked."""
    return check_args(make_parser().parse_args(argv))


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


def resolve_config(args: argparse.Namespace, command: str = "agents.train") -> dict[str, Any]:
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
    record = {
        "algo": args.algo,
        "env_id": args.env,
        "seed": args.seed,
        "conf_file": str(config_path(args.algo, args.conf_file)),
        "overrides": {"env_kwargs": env_over, "hyperparams": hp_over,
                      "n_timesteps": args.n_timesteps},
        "save_freq": args.save_freq,
        "eval": {"eval_freq": args.eval_freq, "n_eval_episodes": args.eval_episodes,
                 "eval_seed": args.eval_seed, "success_kwargs": success_kwargs(args.env),
                 "stop_success": args.stop_success},
        "device": args.device,
        "torch_threads": args.torch_threads,
        "trained_agent": None,  # the start model's provenance (start_from), if any
        "vec_env": vec_env,
        "versions": versions(),
        "command": f"python -m {command} " + shlex.join(sys.argv[1:]),
        "started": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    return {"hyperparams": hp, "record": record}


class HeldOutEvalCallback(EvalCallback):
    """EvalCallback on a fixed goal set: logs the success rate and the final errors, keeps
    the best model (``best_model.zip``) and its statistics by (success rate, -median error)."""

    def __init__(self, targets: tuple[str, ...], run_dir: Path,
                 stop_success: float | None = None, **kwargs: Any):
        super().__init__(best_model_save_path=None, **kwargs)
        self.targets = targets
        #: Stop training once the validation success rate reaches this (None: never).
        self.stop_success = stop_success
        #: Env steps at which training stopped on ``stop_success`` (None: it did not).
        self.stopped_at: int | None = None
        self.run_dir = run_dir
        self.best_key: tuple[float, float] | None = None
        self.best_summary: dict[str, Any] | None = None
        self._errors: list[dict[str, float]] = []

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        if locals_["done"]:
            self._errors.append(final_errors(locals_["info"], self.targets))

    def _on_step(self) -> bool:
        if not (self.eval_freq > 0 and self.n_calls % self.eval_freq == 0):
            return True
        self.eval_env.env_method("rewind")  # same validation goals every time
        self._errors = []
        keep_going = super()._on_step()
        summary = summarize(self.targets, self._is_success_buffer, self._errors)
        for key, value in summary.items():
            if key.startswith("median_") or key.startswith("max_"):
                self.logger.record(f"eval/final_{key}", value)
        rank = (summary["success_rate"], -error_score(summary, self.targets))
        if self.best_key is None or rank > self.best_key:
            self.best_key = rank
            self.best_summary = {"timesteps": int(self.num_timesteps), **summary}
            self.model.save(self.run_dir / f"{BEST_MODEL}.zip")
            vecnorm = self.model.get_vec_normalize_env()
            if vecnorm is not None:
                save_vecnormalize(vecnorm, self.run_dir / f"{BEST_MODEL}_vecnormalize")
            self.logger.record("eval/best_success_rate", summary["success_rate"])
        if self.verbose:
            errs = ", ".join(f"{k} {v:.3g}" for k, v in summary.items() if "median" in k)
            print(f"validation: success {summary['success_rate']:.0%}, {errs}")
        self.logger.dump(self.num_timesteps)
        if self.stop_success is not None and summary["success_rate"] >= self.stop_success:
            self.stopped_at = int(self.num_timesteps)
            if self.verbose:
                print(f"validation success >= {self.stop_success:.0%}: training stops")
            return False
        return keep_going


class Checkpoints(CheckpointCallback):
    """SB3's CheckpointCallback (``rl_model_<n>_steps.zip``, VecNormalize pickle) that also
    writes the statistics as plain arrays (``rl_model_vecnormalize_<n>_steps.npz``)."""

    def _on_step(self) -> bool:
        keep_going = super()._on_step()
        vecnorm = self.model.get_vec_normalize_env()
        if self.n_calls % self.save_freq == 0 and vecnorm is not None:
            save_stats(vecnorm, self._checkpoint_path("vecnormalize_", extension="npz"))
        return keep_going


def build(config: dict[str, Any], verbose: int = 1) -> tuple[Any, Any]:
    """The algorithm (on its training envs) and the validation env of a run config.

    Everything a hyper-parameter can break is built here, before the run directory exists;
    any failure is a :class:`UserError` naming the algorithm.
    """
    import torch

    hp, rec = config["hyperparams"], config["record"]
    torch.set_num_threads(rec["torch_threads"])
    set_random_seed(rec["seed"])
    env_id, algo, seed = rec["env_id"], rec["algo"], rec["seed"]
    kwargs = algo_kwargs(algo, hp)
    norm = normalize_kwargs(hp["normalize"])
    wrapper = hp.get("env_wrapper")
    env = make_sb3_vec_env(env_id, hp["n_envs"], seed, hp["env_kwargs"], rec["vec_env"],
                           env_wrapper=wrapper)
    ev = rec["eval"]
    # with the native env the wrappers are VecEnv wrappers: the validation env gets the same
    # chain (VecNormalize's statistics sync walks both chains level by level)
    vector = rec["vec_env"] == "native"
    eval_env = make_vec_env(
        env_id, 1, {**hp["env_kwargs"], **ev["success_kwargs"]}, None,
        seeds=goal_seeds(ev["eval_seed"], ev["n_eval_episodes"]),
        env_wrapper=None if vector else wrapper,
    )
    if vector:
        for cls, wkw in vector_wrappers(wrapper):
            eval_env = cls(eval_env, **wkw)
    try:
        if norm is not None:
            norm_kw = {"gamma": kwargs.get("gamma", 0.99), **norm}
            env = VecNormalize(env, **norm_kw)
            eval_env = VecNormalize(eval_env, **{**norm_kw, "training": False,
                                                 "norm_reward": False})
        model = algo_class(algo)(hp["policy"], env, seed=seed, device=rec["device"],
                                 verbose=verbose, **kwargs)
    except Exception as exc:  # SB3 raises ValueError/TypeError/AssertionError/KeyError...
        env.close()
        eval_env.close()
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise UserError(f"cannot build {algo.upper()} from the hyper-parameters: {msg}") from None
    return model, eval_env


def start_from(model: Any, spec: str, record: dict[str, Any]) -> None:
    """Load the weights and observation statistics of the saved model ``spec`` into ``model``
    (same algorithm and policy, same observation and action spaces; the env id may differ).
    The source's path, sha256, env id, steps and wall time go to ``record["trained_agent"]``.
    """
    from agents.loading import ModelPolicy
    from agents.model_files import sha256

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
    record["trained_agent"] = {
        "path": str(src.path), "sha256": sha256(src.path), "env_id": src.env_id,
        "total_timesteps": src.run.record.get("total_timesteps"),
        "wall_time_s": src.run.record.get("wall_time_s")}


def train(config: dict[str, Any], run_dir: Path, model: Any, eval_env: Any,
          progress_bar: bool = True) -> Any:
    """Learn (validation and checkpoints as configured), save the run; returns the model."""
    from stable_baselines3.common.logger import configure

    hp, rec = config["hyperparams"], config["record"]
    env_id = rec["env_id"]
    model.set_logger(configure(str(run_dir / "tb" / rec["algo"]),
                               ["stdout", "tensorboard"] if model.verbose else ["tensorboard"]))
    ev = rec["eval"]
    n_envs = hp["n_envs"]
    evaluation = HeldOutEvalCallback(
        targets=task_targets(env_id), run_dir=run_dir, eval_env=eval_env,
        stop_success=ev.get("stop_success"),
        n_eval_episodes=ev["n_eval_episodes"],
        eval_freq=max(ev["eval_freq"] // n_envs, 1) if ev["eval_freq"] > 0 else 0,
        log_path=str(run_dir), deterministic=True, verbose=1,
    )
    callbacks: list[Any] = [evaluation]
    if rec.get("save_freq", 0) > 0:
        callbacks.append(Checkpoints(save_freq=max(rec["save_freq"] // n_envs, 1),
                                     save_path=str(run_dir), name_prefix="rl_model",
                                     save_vecnormalize=True))
    t0 = time.time()
    interrupted = False
    try:
        model.learn(total_timesteps=int(hp["n_timesteps"]), callback=callbacks,
                    progress_bar=progress_bar)
    except KeyboardInterrupt:
        interrupted = True
    model.save(run_dir / f"{env_id}.zip")
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        save_vecnormalize(vecnorm, run_dir / env_id / "vecnormalize")
    rec["wall_time_s"] = round(time.time() - t0, 1)
    rec["total_timesteps"] = int(model.num_timesteps)
    rec["interrupted"] = interrupted
    rec["stopped_on_success_at"] = evaluation.stopped_at
    if evaluation.best_summary is not None:
        rec["best_validation"] = {k: (float(v) if k != "timesteps" else v)
                                  for k, v in evaluation.best_summary.items()}
    write_run_config(run_dir, env_id, hp, rec)
    model.get_env().close()
    eval_env.close()
    return model


def main(argv: Sequence[str] | None = None) -> Path:
    """CLI entry point; returns the run directory.

    Every argument and hyper-parameter is validated (envs, wrappers, algorithm built) before
    the run directory is created: a rejected input leaves nothing behind.
    """
    args = parse_args(argv)
    config = resolve_config(args)
    hp, rec = config["hyperparams"], config["record"]
    probe = make_env(args.env, hp["env_kwargs"], hp.get("env_wrapper"))
    rec["env_signature"] = env_signature(probe)  # checked when the model is loaded
    probe.close()
    model, eval_env = build(config, verbose=args.verbose)
    if args.trained_agent is not None:
        start_from(model, args.trained_agent, rec)
    run_dir = next_run_dir(Path(args.log_folder), args.algo, args.env, args.run_name)
    if run_dir.exists():
        raise UserError(f"run directory {run_dir} exists (choose another --run-name)")
    (run_dir / args.env).mkdir(parents=True)
    write_args(run_dir, args.env, {
        "algo": args.algo, "seed": args.seed, "conf_file": rec["conf_file"],
        "n_timesteps": hp["n_timesteps"], "device": args.device,
        "num_threads": args.torch_threads, "vec_env": rec["vec_env"],
        "eval_freq": args.eval_freq, "eval_episodes": args.eval_episodes,
        "save_freq": args.save_freq, "log_folder": str(args.log_folder)})
    write_run_config(run_dir, args.env, hp, rec)  # rewritten at the end (results, checksums)
    print(f"run directory: {run_dir}")
    train(config, run_dir, model, eval_env, progress_bar=not args.no_progress_bar)
    print(f"saved {run_dir / (args.env + '.zip')} ({rec['wall_time_s']} s)")
    return run_dir


if __name__ == "__main__":
    run_cli(main)
