"""Train a Stable-Baselines3 agent on a soft-hand task (a thin CLI, RL-Zoo style).

Hyper-parameters come from ``softhand_env/configs/agents/<algo>.yml`` (a mapping keyed by env
id, see that file) and nowhere else; the CLI only picks the entry and applies overrides::

    python -m agents.train --algo ppo --env SoftHandTranslate-v0 --seed 0
    python -m agents.train --algo sac --env SoftHandReorient-v0 --n-timesteps 20000 \\
        --env-kwargs max_delta_deg:0.5 --hyperparams learning_rate:1e-3 --log-folder logs

The run directory ``<log-folder>/<algo>/<env_id>_<k>/`` receives the config actually used
(``config.yml``: YAML entry + overrides, seed, package versions, command, wall time), the final
model and its VecNormalize statistics (``model.zip``, ``vecnormalize.pkl``), the best model on
the validation goals (``best/``), checkpoints, ``evaluations.npz`` and TensorBoard logs (``tb/``).
Evaluate it with ``python -m agents.evaluate --model <run dir>``.

Evaluation during training (:class:`HeldOutEvalCallback`) plays a fixed validation goal set
(``--eval-seed``, default 5000: episode k starts with ``reset(seed=5000 + k)``), disjoint from
the test goals of :mod:`agents.evaluate` (seed 10000), with issue 6's success tolerance (1 mm /
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

import yaml
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

from agents import policies  # noqa: F401  (registers AsymmetricPolicy / BlindActorPolicy)
from agents.common import (
    ALGOS,
    CONFIG_FILE,
    MODEL_FILE,
    VECNORM_FILE,
    UserError,
    algo_class,
    algo_kwargs,
    check_env_id,
    config_path,
    error_score,
    final_errors,
    goal_seeds,
    load_hyperparams,
    make_env,
    make_vec_env,
    normalize_kwargs,
    parse_kv,
    run_cli,
    success_kwargs,
    summarize,
    task_targets,
    versions,
)
from agents.native_vec_env import make_sb3_vec_env
from softhand_env.envs.signature import env_signature


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Command-line arguments (see ``python -m agents.train --help``)."""
    p = argparse.ArgumentParser(
        prog="python -m agents.train", description=__doc__.split("\n\n")[0]
    )
    p.add_argument("--env", required=True, help="environment id, e.g. SoftHandTranslate-v0")
    p.add_argument("--algo", default="ppo", choices=sorted(ALGOS))
    p.add_argument("--conf-file", default=None,
                   help="hyper-parameter YAML (default softhand_env/configs/agents/<algo>.yml)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY:VALUE",
                   help="override env_kwargs of the entry (values parsed as YAML)")
    p.add_argument("--hyperparams", nargs="*", default=[], metavar="KEY:VALUE",
                   help="override algorithm keys of the entry (values parsed as YAML)")
    p.add_argument("--n-timesteps", type=int, default=None, help="override n_timesteps")
    p.add_argument("--log-folder", default="logs")
    p.add_argument("--run-name", default=None, help="run directory name (default <env>_<k>)")
    p.add_argument("--eval-freq", type=int, default=50_000,
                   help="evaluate every this many env steps (<= 0: never)")
    p.add_argument("--eval-episodes", type=int, default=20, help="validation goals")
    p.add_argument("--eval-seed", type=int, default=5000, help="seed of the validation goals")
    p.add_argument("--save-freq", type=int, default=250_000,
                   help="checkpoint every this many env steps (<= 0: never)")
    p.add_argument("--device", default="cpu")
    p.add_argument("--torch-threads", type=int, default=1)
    p.add_argument("--no-progress-bar", action="store_true")
    p.add_argument("--verbose", type=int, default=1)
    return p.parse_args(argv)


def next_run_dir(log_folder: Path, algo: str, env_id: str, name: str | None) -> Path:
    """``<log_folder>/<algo>/<name>`` or the first free ``<env_id>_<k>`` (k = 1, 2, ...)."""
    base = log_folder / algo
    if name is not None:
        return base / name
    k = 1
    while (base / f"{env_id}_{k}").exists():
        k += 1
    return base / f"{env_id}_{k}"


def resolve_config(args: argparse.Namespace) -> dict[str, Any]:
    """The run config: YAML entry merged with the CLI overrides (JSON/YAML-serialisable)."""
    check_env_id(args.env)
    hp = load_hyperparams(args.algo, args.env, args.conf_file)
    env_over = parse_kv(args.env_kwargs, "--env-kwargs")
    hp_over = parse_kv(args.hyperparams, "--hyperparams")
    hp.update(hp_over)
    hp["env_kwargs"] = {**hp["env_kwargs"], **env_over}
    if args.n_timesteps is not None:
        if args.n_timesteps < 1:
            raise UserError("--n-timesteps must be >= 1")
        hp["n_timesteps"] = args.n_timesteps
    n_envs = hp["n_envs"]
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise UserError(f"n_envs must be an int >= 1 (got {n_envs!r})")
    if args.eval_episodes < 1:
        raise UserError("--eval-episodes must be >= 1")
    return {
        "algo": args.algo,
        "env_id": args.env,
        "seed": args.seed,
        "conf_file": str(config_path(args.algo, args.conf_file)),
        "hyperparams": hp,
        "overrides": {"env_kwargs": env_over, "hyperparams": hp_over,
                      "n_timesteps": args.n_timesteps},
        "save_freq": args.save_freq,
        "eval": {"eval_freq": args.eval_freq, "n_eval_episodes": args.eval_episodes,
                 "eval_seed": args.eval_seed, "success_kwargs": success_kwargs(args.env)},
        "device": args.device,
        "torch_threads": args.torch_threads,
        "versions": versions(),
        "command": "python -m agents.train " + shlex.join(sys.argv[1:]),
        "started": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def save_config(config: dict[str, Any], run_dir: Path) -> None:
    """Write ``config.yml`` into the run directory."""
    with (run_dir / CONFIG_FILE).open("w") as fh:
        yaml.safe_dump(config, fh, sort_keys=False)


class HeldOutEvalCallback(EvalCallback):
    """EvalCallback on a fixed goal set: logs the success rate and the final errors, keeps
    the best model (and its VecNormalize statistics) by (success rate, -median error)."""

    def __init__(self, targets: tuple[str, ...], best_dir: Path, **kwargs: Any):
        super().__init__(best_model_save_path=None, **kwargs)
        self.targets = targets
        self.best_dir = best_dir
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
        key = (summary["success_rate"], -error_score(summary, self.targets))
        if self.best_key is None or key > self.best_key:
            self.best_key = key
            self.best_summary = {"timesteps": int(self.num_timesteps), **summary}
            self.best_dir.mkdir(parents=True, exist_ok=True)
            self.model.save(self.best_dir / MODEL_FILE)
            vecnorm = self.model.get_vec_normalize_env()
            if vecnorm is not None:
                vecnorm.save(str(self.best_dir / VECNORM_FILE))
            self.logger.record("eval/best_success_rate", summary["success_rate"])
        if self.verbose:
            errs = ", ".join(f"{k} {v:.3g}" for k, v in summary.items() if "median" in k)
            print(f"validation: success {summary['success_rate']:.0%}, {errs}")
        self.logger.dump(self.num_timesteps)
        return keep_going



def make_eval_callback(config: dict[str, Any], run_dir: Path, eval_env: Any) -> HeldOutEvalCallback:
    """The validation callback of a run (every ``eval_freq`` env steps, best model in ``best/``)."""
    ev = config["eval"]
    n_envs = config["hyperparams"]["n_envs"]
    return HeldOutEvalCallback(
        targets=task_targets(config["env_id"]),
        best_dir=run_dir / "best",
        eval_env=eval_env,
        n_eval_episodes=ev["n_eval_episodes"],
        eval_freq=max(ev["eval_freq"] // n_envs, 1) if ev["eval_freq"] > 0 else 0,
        log_path=str(run_dir),
        deterministic=True,
        verbose=1,
    )


def train(config: dict[str, Any], run_dir: Path, progress_bar: bool = True, verbose: int = 1):
    """Build envs, model and callbacks from ``config``, learn, save; returns the model."""
    import torch

    torch.set_num_threads(config["torch_threads"])
    set_random_seed(config["seed"])
    hp = config["hyperparams"]
    env_id, algo, seed = config["env_id"], config["algo"], config["seed"]
    kwargs = algo_kwargs(algo, hp)
    norm = normalize_kwargs(hp["normalize"])
    wrapper = hp.get("env_wrapper")
    env = make_sb3_vec_env(env_id, hp["n_envs"], seed, hp["env_kwargs"], hp["vec_env"],
                           env_wrapper=wrapper)
    ev = config["eval"]
    eval_env = make_vec_env(
        env_id, 1, {**hp["env_kwargs"], **ev["success_kwargs"]}, None,
        seeds=goal_seeds(ev["eval_seed"], ev["n_eval_episodes"]), env_wrapper=wrapper,
    )
    if norm is not None:
        norm_kw = {"gamma": kwargs.get("gamma", 0.99), **norm}
        env = VecNormalize(env, **norm_kw)
        eval_env = VecNormalize(eval_env, **{**norm_kw, "training": False, "norm_reward": False})
    model = algo_class(algo)(
        hp["policy"], env, seed=seed, device=config["device"], verbose=verbose,
        tensorboard_log=str(run_dir / "tb"), **kwargs,
    )
    callbacks = [make_eval_callback(config, run_dir, eval_env)]
    if config.get("save_freq", 0) > 0:
        callbacks.append(
            CheckpointCallback(
                save_freq=max(config["save_freq"] // hp["n_envs"], 1),
                save_path=str(run_dir / "checkpoints"),
                name_prefix="model",
                save_vecnormalize=True,
            )
        )
    t0 = time.time()
    interrupted = False
    try:
        model.learn(
            total_timesteps=int(hp["n_timesteps"]), callback=callbacks,
            progress_bar=progress_bar, tb_log_name=algo,
        )
    except KeyboardInterrupt:
        interrupted = True
    model.save(run_dir / MODEL_FILE)
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        vecnorm.save(str(run_dir / VECNORM_FILE))
    config["wall_time_s"] = round(time.time() - t0, 1)
    config["total_timesteps"] = int(model.num_timesteps)
    config["interrupted"] = interrupted
    best = callbacks[0].best_summary
    if best is not None:
        config["best_validation"] = {k: (float(v) if k != "timesteps" else v)
                                     for k, v in best.items()}
    save_config(config, run_dir)
    env.close()
    eval_env.close()
    return model


def main(argv: Sequence[str] | None = None) -> Path:
    """CLI entry point; returns the run directory."""
    args = parse_args(argv)
    config = resolve_config(args)
    hp = config["hyperparams"]
    algo_kwargs(args.algo, hp)  # validate everything before creating the run directory
    probe = make_env(args.env, hp["env_kwargs"], hp.get("env_wrapper"))
    config["env_signature"] = env_signature(probe)  # checked when the model is loaded
    probe.close()
    run_dir = next_run_dir(Path(args.log_folder), args.algo, args.env, args.run_name)
    run_dir.mkdir(parents=True, exist_ok=True)
    save_config(config, run_dir)
    print(f"run directory: {run_dir}")
    train(config, run_dir, progress_bar=not args.no_progress_bar, verbose=args.verbose)
    print(f"saved {run_dir / MODEL_FILE} ({config['wall_time_s']} s)")
    return run_dir


if __name__ == "__main__":
    run_cli(main)
