"""End-to-end PPO training throughput: ``python -m agents.bench_train [--env ID]``.

Trains PPO for a fixed number of environment steps twice in one run and prints a table of
end-to-end frames (env steps) per second of ``model.learn`` (rollouts, VecNormalize, updates):

* ``dummy``: the env's entry of ``configs/agents/ppo.yml`` as it is (SB3 ``DummyVecEnv`` of
  monitored single envs, its n_envs, n_steps, batch size and epochs), torch on one thread;
* ``native``: the same entry (network, learning rate, gamma, normalisation, env keywords)
  through :class:`~agents.sb3.native_vec_env.NativeVecEnv` with the rollout/update shape tuned for
  it: many environments stepped in one batched call, fewer epochs over larger minibatches
  (``--native-*`` options; defaults below).

* ``rllib`` (with ``--rllib``; needs ``softhand-env[rllib]``): the same entry translated to
  RLlib PPO (:mod:`agents.rllib.settings`: its network, coefficients and train batch of
  n_envs x n_steps env steps, observations through RLlib's filter, no reward normalisation)
  on a local Ray of ``--rllib-env-runners`` env runners of ``--rllib-envs-per-runner`` envs,
  the learner in this process; one iteration runs before the clock starts (it starts the
  runners' envs), then whole iterations until ``--steps`` env steps.

The last line is ``native/dummy fps ratio: <float>``. The environments are built and their
kernels compiled before the clock starts; the load average of the machine is printed, since
the figures are only meaningful relative to it. Timing is reported, never asserted.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Sequence
from typing import Any

from agents.common.cli import SEED_MAX, ArgumentParser, UserError, check_range, run_cli

#: Rollout/update shape of the native run: 8192 samples per update, 20 minibatch steps.
#: Measured alternatives (Reorient, 2 shared cores, load ~1.7; env steps/s): batch 4096 x 4
#: epochs 22k; 128 x 64 envs/steps, batch 1024 x 5 epochs 15k (5.6k with 2 torch threads:
#: torch threads compete with the numba threads of the batched physics); batch 1024 x 10
#: epochs 13.5k.
NATIVE_DEFAULTS: dict[str, int] = {
    "n_envs": 256,
    "n_steps": 32,
    "batch_size": 2048,
    "n_epochs": 5,
    "torch_threads": 1,
}


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = ArgumentParser(prog="python -m agents.bench_train",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="SoftHandReorient-v0",
                   help="environment id with a ppo.yml entry and no env_wrapper")
    p.add_argument("--steps", type=int, default=65_536, help="env steps per run")
    p.add_argument("--seed", type=int, default=0)
    for key, value in NATIVE_DEFAULTS.items():
        p.add_argument(f"--native-{key.replace('_', '-')}", type=int, default=value,
                       dest=f"native_{key}")
    p.add_argument("--native-numba-threads", type=int, default=None,
                   help="threads of the batched physics (default: numba's, one per core)")
    p.add_argument("--dummy-torch-threads", type=int, default=1)
    p.add_argument("--rllib", action="store_true",
                   help="also train with RLlib PPO (softhand-env[rllib]) on a local Ray")
    p.add_argument("--rllib-env-runners", type=int, default=2, metavar="K")
    p.add_argument("--rllib-envs-per-runner", type=int, default=8, metavar="M")
    args = p.parse_args(argv)
    if args.native_numba_threads is not None and args.native_numba_threads < 1:
        p.error("--native-numba-threads must be >= 1")
    for key in ["steps", *(f"native_{k}" for k in NATIVE_DEFAULTS), "dummy_torch_threads",
                "rllib_env_runners", "rllib_envs_per_runner"]:
        if getattr(args, key) < 1:
            p.error(f"--{key.replace('_', '-')} must be >= 1")
    check_range("--steps", args.steps, 1, 10**9)
    check_range("--seed", args.seed, 0, SEED_MAX)
    return args


def run_ppo(env_id: str, hp: dict[str, Any], vec_env: str, steps: int, seed: int,
            torch_threads: int, numba_threads: int | None = None) -> dict[str, Any]:
    """Build the VecEnv and PPO of ``hp`` (a ppo.yml entry) and time ``learn(steps)``.

    ``numba_threads``: threads of the batched physics (None: numba's default, one per core).
    Returns a row of the table: settings, wall time (s) of ``learn`` and env steps per second.
    """
    import numba
    import numpy as np
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.runs.hyperparams import algo_kwargs, normalize_kwargs
    from agents.sb3.native_vec_env import make_sb3_vec_env

    torch.set_num_threads(torch_threads)
    numba.set_num_threads(numba_threads or numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
    kwargs = algo_kwargs("ppo", hp)
    warm = make_sb3_vec_env(env_id, 2, seed, hp["env_kwargs"], vec_env,
                            env_wrapper=hp.get("env_wrapper"))
    warm.reset()  # compiles / loads the kernels outside the clock
    warm.step(np.zeros((2, *np.shape(warm.action_space.sample())), dtype=np.float32))
    warm.close()
    env = make_sb3_vec_env(env_id, hp["n_envs"], seed, hp["env_kwargs"], vec_env,
                           env_wrapper=hp.get("env_wrapper"))
    norm = normalize_kwargs(hp["normalize"])
    if norm is not None:
        env = VecNormalize(env, **{"gamma": kwargs.get("gamma", 0.99), **norm})
    model = PPO(hp["policy"], env, seed=seed, device="cpu", verbose=0, **kwargs)
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps)
    wall = time.perf_counter() - t0
    done = int(model.num_timesteps)
    env.close()
    return {
        "vec_env": vec_env,
        "n_envs": hp["n_envs"],
        "n_steps": kwargs["n_steps"],
        "batch_size": kwargs["batch_size"],
        "n_epochs": kwargs["n_epochs"],
        "threads": f"{torch_threads}/{numba.get_num_threads() if vec_env == 'native' else '-'}",
        "steps": done,
        "wall_s": wall,
        "fps": done / wall,
    }


def run_rllib(env_id: str, hp: dict[str, Any], steps: int, seed: int, runners: int,
              envs_per_runner: int) -> dict[str, Any]:
    """RLlib PPO of ``hp`` (a ppo.yml entry) on a local Ray of ``runners`` CPUs: one warm-up
    iteration, then whole iterations timed until ``steps`` env steps. Returns a row of the
    table (``n_envs``: all runners' envs; ``n_steps``: env steps per env and iteration)."""
    import ray

    from agents.play.sharding import LOCAL, cluster_cpus
    from agents.rllib.algorithm import (
        TORCH_THREADS,
        Sampling,
        TrainProgress,
        build_algorithm,
        require_rllib,
        train_until,
    )
    from agents.rllib.settings import ppo_settings

    require_rllib("--rllib")
    settings = ppo_settings(hp)
    started = not ray.is_initialized()
    cluster_cpus(LOCAL, runners, flag="--rllib")
    algo = build_algorithm(settings, Sampling(env_id, dict(hp["env_kwargs"]),
                                              hp.get("env_wrapper"), runners,
                                              envs_per_runner, seed))
    try:
        warm = train_until(algo, 1)
        timed = train_until(algo, warm.env_steps + steps,
                            TrainProgress(env_steps=warm.env_steps))
    finally:
        algo.stop()
        if started:
            ray.shutdown()
    done = timed.env_steps - warm.env_steps
    n_envs = max(1, runners) * envs_per_runner
    return {
        "vec_env": "rllib", "n_envs": n_envs,
        "n_steps": settings.train_batch_size // n_envs,
        "batch_size": settings.minibatch_size, "n_epochs": settings.num_epochs,
        "threads": f"{TORCH_THREADS}/-", "steps": done, "wall_s": timed.wall_s,
        "fps": done / timed.wall_s,
    }


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown table of the runs."""
    cols = ["vec_env", "n_envs", "n_steps", "batch_size", "n_epochs", "threads", "steps",
            "wall_s", "fps"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        cells = [f"{r[c]:.1f}" if c == "wall_s" else f"{r[c]:,.0f}" if c == "fps" else str(r[c])
                 for c in cols]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> float:
    """Run both trainings, print the table and the ratio; returns the ratio."""
    args = parse_args(argv)
    if args.rllib:
        from agents.rllib.algorithm import require_rllib

        require_rllib("--rllib")  # before any run
    import softhand_env  # noqa: F401  (registers the environments)
    from agents.runs.hyperparams import load_hyperparams

    hp = load_hyperparams("ppo", args.env)
    if hp.get("env_wrapper"):
        raise UserError(f"{args.env}'s ppo.yml entry uses env_wrapper, which the native "
                        "vector env cannot take; choose another --env")
    native_hp = {**hp, **{k: getattr(args, f"native_{k}") for k in NATIVE_DEFAULTS
                          if k != "torch_threads"}}
    cpus = os.cpu_count()
    print(f"{args.env}: PPO, {args.steps:,} env steps per run, {cpus} CPUs, "
          f"load average before {os.getloadavg()[0]:.2f}")
    rows = [
        run_ppo(args.env, hp, "dummy", args.steps, args.seed, args.dummy_torch_threads),
        run_ppo(args.env, native_hp, "native", args.steps, args.seed,
                args.native_torch_threads, args.native_numba_threads),
    ]
    if args.rllib:
        rows.append(run_rllib(args.env, hp, args.steps, args.seed, args.rllib_env_runners,
                              args.rllib_envs_per_runner))
    print(table(rows))
    print("threads = torch / numba (the batched physics of the native env); rllib: "
          f"{args.rllib_env_runners} env runners (one CPU each) x "
          f"{args.rllib_envs_per_runner} envs, torch threads of the learner and of each runner")
    print(f"load average after {os.getloadavg()[0]:.2f}")
    if args.rllib:
        print(f"rllib/dummy fps ratio: {rows[2]['fps'] / rows[0]['fps']:.2f}")
    ratio = rows[1]["fps"] / rows[0]["fps"]
    print(f"native/dummy fps ratio: {ratio:.2f}")
    return ratio


if __name__ == "__main__":
    run_cli(main)
