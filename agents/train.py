"""Train a Stable-Baselines3 agent on a soft-hand task (a thin CLI, RL-Zoo style).

Hyper-parameters come from ``agents/configs/<algo>.yml`` (a mapping keyed by env
id, see that file) and nowhere else; the CLI only picks the entry and applies overrides::

    python -m agents.train --algo ppo --env SoftHandTranslate-v0 --seed 0
    python -m agents.train --algo sac --env SoftHandReorient-v0 --n-timesteps 20000 \\
        --env-kwargs max_delta_deg:0.5 --hyperparams learning_rate:1e-3 --log-folder logs

The run directory ``<log-folder>/<algo>/<env_id>_<k>/`` is laid out as RL Zoo's (see
:mod:`agents.runs.layout`): the final model ``<env_id>.zip``; ``<env_id>/config.yml`` (the YAML
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

import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback

from agents.common.cli import UserError, check_run_location, run_cli
from agents.common.env_factory import task_targets
from agents.common.metrics import error_score, final_errors, summarize, summary_success_text
from agents.runs.layout import BEST_MODEL
from agents.runs.normalization import save_stats
from agents.runs.records import RunConfig, TrainOutcome
from agents.runs.writing import save_vecnormalize, write_args, write_run_config
from agents.sb3.finetune import CriticWarmup, FineTune, add_arguments, set_log_std
from agents.sb3.interrupts import DeferredSignals, StopOnSignal
from agents.sb3.threads import PhaseThreads
from agents.sb3.training import (
    TrainSettings,
    build,
    make_parser,
    next_run_dir,
    probe_signature,
    resolve_config,
    rewind_validation,
    start_from,
)


@dataclasses.dataclass
class TrainCommand(TrainSettings):
    """The command line of ``agents.train``: the training settings and the fine-tuning ones
    (:mod:`agents.sb3.finetune`)."""

    finetune: FineTune = dataclasses.field(default_factory=FineTune)


def parse_args(argv: Sequence[str] | None = None) -> TrainCommand:
    """Command-line arguments (see ``python -m agents.train --help``), range-checked."""
    parser = make_parser()
    add_arguments(parser)
    ns = parser.parse_args(argv)
    settings = TrainSettings.from_namespace(ns)
    finetune = FineTune.from_namespace(ns)
    finetune.check_algo(settings.algo)
    return TrainCommand(**dataclasses.asdict(settings), finetune=finetune)


class HeldOutEvalCallback(EvalCallback):
    """EvalCallback on a fixed goal set: logs the success rate and the final errors, keeps
    the best model (``best_model.zip``) and its statistics by (success rate, -median error)."""

    def __init__(self, targets: tuple[str, ...], run_dir: Path, eval_seed: int,
                 stop_success: float | None = None, **kwargs: Any):
        super().__init__(best_model_save_path=None, **kwargs)
        self.targets = targets
        #: Seed of the first validation goal (goal k: ``reset(seed=eval_seed + k)``).
        self.eval_seed = eval_seed
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
        rewind_validation(self.eval_env, self.eval_seed)  # same validation goals every time
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
            print(f"validation: success {summary_success_text(summary)}, {errs}")
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


def train(config: RunConfig, run_dir: Path, model: Any, eval_env: Any,
          progress_bar: bool = True, stop: DeferredSignals | None = None) -> Any:
    """Learn (validation and checkpoints as configured), save the run; returns the model.

    ``stop`` (its handlers installed by the caller, :mod:`agents.sb3.interrupts`) ends
    ``learn()`` after the env step at which SIGINT/SIGTERM arrived; the run is then saved as
    at the end (final zip, statistics, ``config.yml`` with checksums) with
    ``interrupted: true`` in its outcome."""
    from stable_baselines3.common.logger import configure

    hp, rec = config.hyperparams, config.record
    env_id = rec.env_id
    model.set_logger(configure(str(run_dir / "tb" / rec.algo),
                               ["stdout", "tensorboard"] if model.verbose else ["tensorboard"]))
    ev = rec.eval
    n_envs = config.n_envs
    evaluation = HeldOutEvalCallback(
        targets=task_targets(env_id), run_dir=run_dir, eval_env=eval_env,
        eval_seed=ev.eval_seed, stop_success=ev.stop_success,
        n_eval_episodes=ev.n_eval_episodes,
        eval_freq=max(ev.eval_freq // n_envs, 1) if ev.eval_freq > 0 else 0,
        log_path=str(run_dir), deterministic=True, verbose=1,
    )
    callbacks: list[Any] = [] if stop is None else [StopOnSignal(stop)]
    callbacks.append(evaluation)
    if rec.fit_threads is not None and rec.fit_threads != rec.torch_threads:
        callbacks.append(PhaseThreads(rec.torch_threads, rec.fit_threads))
    if rec.finetune is not None and rec.finetune["critic_warmup"] > 0:
        callbacks.append(CriticWarmup(rec.finetune["critic_warmup"],
                                      rec.finetune["critic_warmup_lr"]))
    if rec.save_freq > 0:
        callbacks.append(Checkpoints(save_freq=max(rec.save_freq // n_envs, 1),
                                     save_path=str(run_dir), name_prefix="rl_model",
                                     save_vecnormalize=True))
    t0 = time.time()
    interrupted = False
    try:
        model.learn(total_timesteps=config.n_timesteps, callback=callbacks,
                    progress_bar=progress_bar)
    except KeyboardInterrupt:  # raised by code that ignores the handlers (e.g. a worker)
        interrupted = True
    if stop is not None and stop.signal_name is not None:
        interrupted = True
        print(f"{stop.signal_name}: stopped at {model.num_timesteps} steps; saving the run",
              flush=True)
    model.save(run_dir / f"{env_id}.zip")
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        save_vecnormalize(vecnorm, run_dir / env_id / "vecnormalize")
    best = evaluation.best_summary
    rec.outcome = TrainOutcome(
        wall_time_s=round(time.time() - t0, 1),
        total_timesteps=int(model.num_timesteps),
        interrupted=interrupted,
        stopped_on_success_at=evaluation.stopped_at,
        best_validation=None if best is None else {
            k: (float(v) if k != "timesteps" else v) for k, v in best.items()},
    )
    write_run_config(run_dir, env_id, hp, rec)
    model.get_env().close()
    eval_env.close()
    return model


def main(argv: Sequence[str] | None = None) -> Path:
    """CLI entry point; returns the run directory.

    Every argument and hyper-parameter is validated (output location, envs, wrappers,
    algorithm built) before the run directory is created: a rejected input leaves nothing
    behind. The log folder must be writable and outside the package's model folder. From the
    creation of the run directory on, SIGINT and SIGTERM stop training between steps and the
    run is saved and finalised (:mod:`agents.sb3.interrupts`).
    """
    args = parse_args(argv)
    check_run_location(args.log_folder)
    run_dir = next_run_dir(Path(args.log_folder), args.algo, args.env, args.run_name)
    if run_dir.exists():
        raise UserError(f"run directory {run_dir} exists (choose another --run-name)")
    config = resolve_config(args)
    hp, rec = config.hyperparams, config.record
    # checked when the model is loaded; the grasp phase is tried here, before the run exists
    rec.env_signature = probe_signature(args.env, config.env_kwargs, config.env_wrapper,
                                        args.seed)
    model, eval_env = build(config, verbose=args.verbose)
    if args.trained_agent is not None:
        start_from(model, args.trained_agent, rec)
    if args.finetune.log_std is not None:
        set_log_std(model, args.finetune.log_std)
    rec.finetune = args.finetune.to_yaml()
    if run_dir.exists():  # created meanwhile by another process
        raise UserError(f"run directory {run_dir} exists (choose another --run-name)")
    stop = DeferredSignals("training")
    with stop.installed():
        (run_dir / args.env).mkdir(parents=True)
        write_args(run_dir, args.env, {
            "algo": args.algo, "seed": args.seed, "conf_file": rec.conf_file,
            "n_timesteps": config.n_timesteps, "device": args.device,
            "num_threads": args.torch_threads, "vec_env": rec.vec_env,
            "eval_freq": args.eval_freq, "eval_episodes": args.eval_episodes,
            "save_freq": args.save_freq, "log_folder": str(args.log_folder)})
        write_run_config(run_dir, args.env, hp, rec)  # rewritten at the end (results, sha256)
        print(f"run directory: {run_dir}", flush=True)
        train(config, run_dir, model, eval_env, progress_bar=not args.no_progress_bar,
              stop=stop)
    assert isinstance(rec.outcome, TrainOutcome)
    what = f"interrupted ({stop.signal_name})" if rec.outcome.interrupted else "saved"
    print(f"{what}: {run_dir / (args.env + '.zip')} ({rec.outcome.wall_time_s} s)")
    return run_dir


if __name__ == "__main__":
    run_cli(main)
