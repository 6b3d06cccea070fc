"""Train PPO with Ray RLlib (new API stack) and export it as an ordinary SB3 PPO run.

::

    python -m agents.rllib_train --env SoftHandReorient-v0 --num-env-runners 2 \\
        --stop-timesteps 200000 [--address ADDRESS] [--envs-per-runner M] [--seed S] \\
        [--out DIR]

The network, PPO coefficients, train batch and observation normalisation are the env's entry of
``agents/configs/ppo.yml`` translated to RLlib (:mod:`agents.rllib.settings`). Without
``--address`` a Ray instance is started here with ``max(1, K)`` CPUs (one per env runner; the
learner runs in this process); ``--address`` joins a running cluster (``auto``,
``HOST:6379``, ``ray://HOST:10001``) whose nodes have this package, and the env runners are
spread over its nodes. Training stops after the iteration that reaches ``--stop-timesteps``
env steps.

The trained RLModule and observation filter are exported weight by weight into the run
directory ``<out>/ppo/<env id>_<k>/`` in the layout of ``agents.train``
(:mod:`agents.runs.layout`, :mod:`agents.rllib.export`): play it with ``python -m
agents.evaluate --model <run dir>``, which loads it without unpickling. The run record
(``config.yml``) holds the RLlib and Ray settings and the throughput (env steps per second of
the training iterations). Without Ray RLlib installed, or on a bad argument, one line and exit
code 2.
"""

from __future__ import annotations

import os
import shlex
import sys
from collections.abc import Sequence
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from agents.common.cli import SEED_MAX, ArgumentParser, UserError, check_range, check_run_location
from agents.common.env_factory import check_env_id, make_env
from agents.common.metrics import success_kwargs
from agents.play.sharding import LOCAL, MAX_WORKERS, cluster_cpus
from agents.rllib.algorithm import (
    TORCH_THREADS,
    Sampling,
    TrainProgress,
    build_algorithm,
    filter_state,
    module_weights,
    require_rllib,
    train_until,
)
from agents.rllib.export import EPSILON, write_run
from agents.rllib.settings import PPOSettings, exported_normalize, ppo_settings
from agents.runs.hyperparams import config_path, load_hyperparams, versions
from agents.runs.records import EvalSettings, RLlibOutcome, RunConfig, RunRecord

#: Most envs per env runner.
MAX_ENVS_PER_RUNNER = 256


def parse_args(argv: Sequence[str] | None = None) -> Any:
    """Command-line arguments (``python -m agents.rllib_train --help``), range-checked."""
    p = ArgumentParser(prog="python -m agents.rllib_train",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--env", required=True, help="environment id with a ppo.yml entry")
    p.add_argument("--address", default=None,
                   help="a running Ray cluster (auto, HOST:6379, ray://HOST:10001); default: "
                        "a Ray started here with one CPU per env runner")
    p.add_argument("--num-env-runners", type=int, required=True, metavar="K",
                   help=f"Ray actors that sample (one CPU each), 0 .. {MAX_WORKERS}; 0: this "
                        "process samples")
    p.add_argument("--envs-per-runner", type=int, default=4, metavar="M",
                   help=f"envs stepped by each env runner, 1 .. {MAX_ENVS_PER_RUNNER}")
    p.add_argument("--stop-timesteps", type=int, required=True, metavar="T",
                   help="env steps to train, 1 .. 1e10")
    p.add_argument("--seed", type=int, default=0, help="seed, 0 .. 2**32 - 1")
    p.add_argument("--out", default="logs", metavar="DIR",
                   help="log folder of the run directory <DIR>/ppo/<env id>_<k>")
    args = p.parse_args(argv)
    check_range("--num-env-runners", args.num_env_runners, 0, MAX_WORKERS)
    check_range("--envs-per-runner", args.envs_per_runner, 1, MAX_ENVS_PER_RUNNER)
    check_range("--stop-timesteps", args.stop_timesteps, 1, 10**10)
    check_range("--seed", args.seed, 0, SEED_MAX)
    if args.address is not None and not args.address.strip():
        raise UserError("--address: the address is empty")
    return args


def run_config(args: Any, settings: PPOSettings, hp: dict[str, Any]) -> RunConfig:
    """The exported run's config: the entry with ``normalize`` as exported and ``n_timesteps``
    the steps asked for; the record of an ``agents.train`` run (no validation during training)
    with ``vec_env: rllib``."""
    hp = {**hp, "n_timesteps": args.stop_timesteps,
          "normalize": exported_normalize(settings, EPSILON)}
    record = RunRecord(
        algo="ppo", env_id=args.env, seed=args.seed, conf_file=str(config_path("ppo", None)),
        overrides={"env_kwargs": {}, "hyperparams": {}, "n_timesteps": args.stop_timesteps},
        save_freq=0,
        eval=EvalSettings(eval_freq=0, n_eval_episodes=0, eval_seed=5000,
                          success_kwargs=success_kwargs(args.env), stop_success=None),
        device="cpu", torch_threads=TORCH_THREADS, vec_env="rllib", versions=versions(),
        command="python -m agents.rllib_train " + shlex.join(sys.argv[1:]),
        started=datetime.now(timezone.utc).isoformat(timespec="seconds"),
    )
    return RunConfig(hyperparams=hp, record=record)


def _report(progress: TrainProgress) -> None:
    ret = "-" if progress.last_return is None else f"{progress.last_return:.2f}"
    print(f"iteration {progress.iterations}: {progress.env_steps} env steps, "
          f"{progress.env_steps / max(progress.wall_s, 1e-9):,.0f} steps/s, "
          f"episode return {ret}", flush=True)


def main(argv: Sequence[str] | None = None) -> Path:
    """CLI entry point; returns the run directory. Every argument is checked, and the entry
    translated, before Ray starts or a directory is created."""
    args = parse_args(argv)
    require_rllib()
    check_env_id(args.env)
    hp = load_hyperparams("ppo", args.env)
    settings = ppo_settings(hp)
    check_run_location(args.out, "--out")
    from agents.sb3.training import next_run_dir
    from softhand_env.envs.signature import env_signature

    config = run_config(args, settings, hp)
    probe = make_env(args.env, hp["env_kwargs"], hp.get("env_wrapper"))
    config.record.env_signature = env_signature(probe)  # checked when the model is loaded
    probe.close()
    import ray

    started = not ray.is_initialized()
    address = args.address or LOCAL
    cpus = cluster_cpus(address, max(1, args.num_env_runners) if address == LOCAL else None,
                        flag="--address")
    sampling = Sampling(args.env, dict(hp["env_kwargs"]), hp.get("env_wrapper"),
                        args.num_env_runners, args.envs_per_runner, args.seed)
    print(f"Ray {address} ({cpus} CPUs): PPO on {args.num_env_runners} env runners x "
          f"{args.envs_per_runner} envs, {settings.train_batch_size} env steps per iteration",
          flush=True)
    algo = build_algorithm(settings, sampling)
    try:
        progress = train_until(algo, args.stop_timesteps, report=_report)
        weights, obs_filter = module_weights(algo), filter_state(algo)
    finally:
        algo.stop()
        if started:
            ray.shutdown()
    config.record.outcome = RLlibOutcome(
        wall_time_s=round(progress.wall_s, 1), total_timesteps=progress.env_steps,
        iterations=progress.iterations,
        env_steps_per_s=round(progress.env_steps / max(progress.wall_s, 1e-9), 1),
        ray={"address": address, "num_env_runners": args.num_env_runners,
             "envs_per_runner": args.envs_per_runner, "cluster_cpus": cpus,
             "ray": ray.__version__, "machine_cpus": os.cpu_count()},
        rllib={**asdict(settings), "hidden": list(settings.hidden)})
    run_dir = next_run_dir(Path(args.out), "ppo", args.env, None)  # numbered when written
    zip_path = write_run(run_dir, config, weights, obs_filter, progress.env_steps)
    print(f"saved: {zip_path} ({progress.wall_s:.1f} s, {progress.env_steps} env steps); "
          f"play it with python -m agents.evaluate --model {run_dir}")
    return run_dir


if __name__ == "__main__":
    from agents.common.cli import run_cli

    run_cli(main)
