"""Behaviour cloning on a Minari dataset, saved as an ordinary run (``python -m agents.bc``).

::

    python -m agents.bc --dataset softhand/pose/expert-v0 --log-folder logs
    python -m agents.evaluate --model logs/ppo/SoftHandPose-v0_1 --seed 5000   # validation

The dataset is one of ``agents.collect`` (its metadata name the env id, the collection env's
``gym.make`` keywords and wrappers). The policy is an SB3 PPO ``MlpPolicy`` (actor
``--net-arch`` units per layer, tanh) whose mean action is fitted to the dataset's actions
by mean squared error (Adam, ``--lr``, ``--epochs`` passes in minibatches of
``--batch-size``) on the dataset's observations, standardised by their mean and variance over
the dataset (frozen ``VecNormalize`` statistics, as a run with ``normalize`` keeps them).
Every ``--eval-every`` epochs (and after the last) the policy plays the validation goals
``reset(seed=5000 + k)``, ``--eval-episodes`` of them, on the dataset's evaluation env (the
collection env's agent keywords on the id's benchmark task, the 1 mm / 1 deg success rule);
the best epoch (success rate, then the median final error) is kept.

The result is written in the layout of :mod:`agents.train` (``<log folder>/ppo/<env
id>_<k>``: the PPO zip, ``<env id>/vecnormalize.npz`` (+ ``.pkl`` for RL Zoo), ``args.yml``
and ``config.yml`` with the run record: ``trainer: bc``, the dataset's id, size, policy and
code permalink, the fit and the best validation; the checksums and the env signature as
every run), so ``agents.evaluate --model <run>`` plays it like any model, and ``agents.train
--trained-agent`` can fine-tune it with PPO. Only Box observations are cloned.
"""

from __future__ import annotations

import dataclasses
import shlex
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.cli import (
    SEED_MAX,
    ArgumentParser,
    UserError,
    check_range,
    check_run_location,
    run_cli,
)
from agents.common.env_factory import goal_seeds, make_env, task_targets
from agents.common.metrics import error_score, success_kwargs, summary_success_text
from agents.play.test_scores import VALIDATION_SEED
from agents.runs.task_keywords import AGENT_KEYS

#: The cloned actor's activation and initial log standard deviation (the Pose agent's).
ACTIVATION = "nn.Tanh"
LOG_STD_INIT = -2.0


@dataclass
class BCSettings:
    """The command line (``python -m agents.bc --help``), range-checked: the dataset id, the
    fit (epochs, minibatch, Adam step size, hidden layers), validation (every
    ``eval_every`` epochs on ``eval_episodes`` goals from seed 5000), seed, output (log
    folder, run name), torch device and threads."""

    dataset: str = ""
    epochs: int = 50
    batch_size: int = 256
    lr: float = 1e-3
    net_arch: list[int] = dataclasses.field(default_factory=lambda: [256, 256])
    eval_every: int = 10
    eval_episodes: int = 50
    seed: int = 0
    log_folder: str = "logs"
    run_name: str | None = None
    device: str = "cpu"
    torch_threads: int = 1

    def __post_init__(self) -> None:
        """Range checks (UserError)."""
        check_range("--epochs", self.epochs, 1, 100_000)
        check_range("--batch-size", self.batch_size, 1, 1_000_000)
        if not 0.0 < self.lr <= 1.0:
            raise UserError(f"--lr must be in (0, 1] (got {self.lr!r})")
        if not 1 <= len(self.net_arch) <= 8:
            raise UserError("--net-arch takes 1 .. 8 layer widths")
        for width in self.net_arch:
            check_range("--net-arch", width, 1, 4096)
        check_range("--eval-every", self.eval_every, 1, 100_000)
        check_range("--eval-episodes", self.eval_episodes, 1, 5000)
        check_range("--seed", self.seed, 0, SEED_MAX)
        check_range("--torch-threads", self.torch_threads, 1, 256)


def parse_args(argv: Sequence[str] | None = None) -> BCSettings:
    """Command-line arguments (see ``python -m agents.bc --help``)."""
    p = ArgumentParser(prog="python -m agents.bc", description=__doc__.split("\n\n")[0])
    p.add_argument("--dataset", required=True,
                   help="Minari dataset id of agents.collect (in $MINARI_DATASETS_PATH)")
    p.add_argument("--epochs", type=int, default=50, help="passes over the data, 1 .. 1e5")
    p.add_argument("--batch-size", type=int, default=256, help="minibatch, 1 .. 1e6")
    p.add_argument("--lr", type=float, default=1e-3, help="Adam step size, (0, 1]")
    p.add_argument("--net-arch", type=int, nargs="+", default=[256, 256], metavar="UNITS",
                   help="hidden layer widths of the actor (and of the unused critic)")
    p.add_argument("--eval-every", type=int, default=10, help="validate every N epochs")
    p.add_argument("--eval-episodes", type=int, default=50,
                   help="validation goals reset(seed=5000 + k), 1 .. 5000")
    p.add_argument("--seed", type=int, default=0, help="weights and minibatch order")
    p.add_argument("--log-folder", default="logs",
                   help="runs go to <log folder>/ppo/<env id>_<k> (as agents.train's)")
    p.add_argument("--run-name", default=None, help="run directory name instead of <env id>_<k>")
    p.add_argument("--device", default="cpu", choices=("cpu", "cuda", "auto"))
    p.add_argument("--torch-threads", type=int, default=1, help="1 .. 256")
    ns = p.parse_args(argv)
    return BCSettings(**{f.name: getattr(ns, f.name) for f in dataclasses.fields(BCSettings)})


# ------------------------------------------------------------------------------ the data
@dataclass
class CloningData:
    """What is cloned from a dataset: env id, the run's ``gym.make`` keywords (the collection
    env's agent keywords and episode length) and wrappers, observations (N, obs_dim) and
    actions (N, act_dim) of every step (float32), and the dataset's provenance."""

    env_id: str
    env_kwargs: dict[str, Any]
    env_wrapper: Any
    observations: np.ndarray
    actions: np.ndarray
    provenance: dict[str, Any]


def load_data(dataset_id: str) -> CloningData:
    """The :class:`CloningData` of a local dataset written by ``agents.collect``;
    :class:`UserError` for a missing dataset, one without our metadata or with other than
    Box spaces."""
    try:
        import minari
    except ImportError:
        raise UserError("agents.bc needs Minari (pip install 'softhand-env[data]')") from None
    from agents.offline.collection import dataset_dir

    if not (dataset_dir(dataset_id) / "data").is_dir():
        raise UserError(f"no local dataset {dataset_id!r} in {dataset_dir(None)} "
                        "(MINARI_DATASETS_PATH; write it with python -m agents.collect)")
    dataset = minari.load_dataset(dataset_id)
    meta = dataset.storage.metadata
    if "env_id" not in meta or "env_kwargs" not in meta:
        raise UserError(f"dataset {dataset_id} was not written by agents.collect (no env_id / "
                        "env_kwargs in its metadata)")
    from gymnasium import spaces

    if not (isinstance(dataset.observation_space, spaces.Box)
            and isinstance(dataset.action_space, spaces.Box)):
        raise UserError(f"dataset {dataset_id}: only Box observations and actions are cloned")
    obs, act = [], []
    for ep in dataset.iterate_episodes():
        obs.append(np.asarray(ep.observations[:-1], dtype=np.float32))
        act.append(np.asarray(ep.actions, dtype=np.float32))
    keep = {k: v for k, v in dict(meta["env_kwargs"]).items()
            if k in AGENT_KEYS or k == "max_episode_steps"}
    provenance = {"id": dataset_id, "episodes": int(dataset.total_episodes),
                  "steps": int(dataset.total_steps), "policy": meta.get("policy"),
                  "success_rate": meta.get("success_rate"),
                  "code_permalink": meta.get("code_permalink"),
                  "first_seed": meta.get("first_seed")}
    return CloningData(str(meta["env_id"]), keep, meta.get("env_wrapper"),
                       np.concatenate(obs), np.concatenate(act), provenance)


# ------------------------------------------------------------------------------ the fit
def policy_kwargs_text(net_arch: Sequence[int]) -> str:
    """The run config's ``policy_kwargs`` (RL Zoo's dialect): actor and critic of
    ``net_arch`` units, tanh, initial log std :data:`LOG_STD_INIT`."""
    arch = "[" + ", ".join(str(int(w)) for w in net_arch) + "]"
    return (f"dict(net_arch=dict(pi={arch}, vf={arch}), activation_fn={ACTIVATION}, "
            f"log_std_init={LOG_STD_INIT})")


def hyperparams(data: CloningData, net_arch: Sequence[int]) -> dict[str, Any]:
    """The run's hyper-parameter entry (what ``config.yml`` holds; a PPO entry that
    ``agents.train`` can fine-tune from)."""
    return {
        "env_kwargs": dict(data.env_kwargs),
        "env_wrapper": data.env_wrapper,
        "n_envs": 1,
        "n_timesteps": 1_000_000,
        "normalize": "{'norm_obs': True, 'norm_reward': False}",
        "policy": "MlpPolicy",
        "policy_kwargs": policy_kwargs_text(net_arch),
    }


class _Actor:
    """The model being fitted with the scripted policies' ``predict`` API (deterministic,
    observations standardised with the frozen statistics)."""

    def __init__(self, model: Any, vecnormalize: Any):
        self.model, self.vecnormalize = model, vecnormalize

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        obs = self.vecnormalize.normalize_obs(np.asarray(observation, dtype=np.float32))
        action, _ = self.model.predict(obs, deterministic=True)
        return action, None


def fit(model: Any, vecnormalize: Any, data: CloningData, args: BCSettings, eval_env: Any
        ) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Fit the actor's mean action to the data (module doc) and keep the best validated
    epoch's weights in ``model``; returns its validation summary (``epoch`` added) and every
    validation (epoch, success rate, median errors)."""
    import torch

    from agents.play.rollout import evaluate
    from agents.sb3.policies import mean_action

    policy = model.policy
    x = torch.as_tensor(vecnormalize.normalize_obs(data.observations), dtype=torch.float32)
    y = torch.as_tensor(data.actions, dtype=torch.float32)
    optimizer = torch.optim.Adam(policy.parameters(), lr=args.lr)
    rng = np.random.default_rng(args.seed)
    targets = task_targets(data.env_id)
    seeds = goal_seeds(VALIDATION_SEED, args.eval_episodes)
    best: dict[str, float] | None = None
    best_state: dict[str, Any] = {}
    curve: list[dict[str, float]] = []
    for epoch in range(1, args.epochs + 1):
        policy.set_training_mode(True)
        order = rng.permutation(len(x))
        total = 0.0
        for start in range(0, len(order), args.batch_size):
            idx = torch.as_tensor(order[start:start + args.batch_size])
            loss = torch.nn.functional.mse_loss(mean_action(policy, x[idx]), y[idx])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += loss.item() * len(idx)
        if epoch % args.eval_every and epoch != args.epochs:
            continue
        policy.set_training_mode(False)
        summary, _ = evaluate(eval_env, _Actor(model, vecnormalize), seeds, targets)
        summary = {**summary, "epoch": float(epoch), "train_mse": total / len(x)}
        curve.append({k: float(v) for k, v in summary.items()})
        print(f"epoch {epoch}: train mse {total / len(x):.3g}, validation success "
              f"{summary_success_text(summary)}", flush=True)
        rank = (summary["success_rate"], -error_score(summary, targets))
        if best is None or rank > (best["success_rate"], -error_score(best, targets)):
            best = summary
            best_state = {k: v.detach().clone() for k, v in policy.state_dict().items()}
    assert best is not None
    policy.load_state_dict(best_state)
    return best, curve


# ------------------------------------------------------------------------------ the run
def main(argv: Sequence[str] | None = None) -> Path:
    """CLI entry point; returns the run directory."""
    args = parse_args(argv)
    check_run_location(args.log_folder)
    if args.run_name is not None and (not args.run_name or "/" in args.run_name):
        raise UserError("--run-name must be a plain directory name")
    data = load_data(args.dataset)
    from agents.sb3.training import next_run_dir

    run_dir = next_run_dir(Path(args.log_folder), "ppo", data.env_id, args.run_name)
    if run_dir.exists():
        raise UserError(f"run directory {run_dir} exists (choose another --run-name)")
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from agents.runs.hyperparams import versions
    from agents.runs.records import BCOutcome, EvalSettings, RunRecord
    from agents.runs.writing import save_vecnormalize, write_args, write_run_config
    from agents.runs.zoo_dialect import policy_kwargs_from
    from softhand_env.envs.signature import env_signature

    torch.set_num_threads(args.torch_threads)
    torch.manual_seed(args.seed)
    eval_kwargs = {**data.env_kwargs, **success_kwargs(data.env_id)}
    eval_env = make_env(data.env_id, eval_kwargs, data.env_wrapper)
    for name in ("observation_space", "action_space"):
        want, got = getattr(eval_env, name).shape, None
        got = (data.observations if name == "observation_space" else data.actions).shape[1:]
        if tuple(want) != tuple(got):
            raise UserError(f"dataset {args.dataset}: its {name} has shape {got}, the env's "
                            f"{want}")
    hp = hyperparams(data, args.net_arch)
    venv = DummyVecEnv([lambda: make_env(data.env_id, eval_kwargs, data.env_wrapper)])
    vecnormalize = VecNormalize(venv, norm_obs=True, norm_reward=False, training=False)
    rms: Any = vecnormalize.obs_rms  # a RunningMeanStd (Box observations)
    rms.mean = data.observations.mean(axis=0).astype(np.float64)
    rms.var = data.observations.var(axis=0).astype(np.float64)
    rms.count = float(len(data.observations))
    model = PPO("MlpPolicy", vecnormalize, policy_kwargs=policy_kwargs_from(hp["policy_kwargs"]),
                seed=args.seed, device=args.device, n_steps=64, batch_size=64, verbose=0)
    record = RunRecord(
        algo="ppo", env_id=data.env_id, seed=args.seed, conf_file=f"minari:{args.dataset}",
        overrides={"env_kwargs": {}, "hyperparams": {}, "n_timesteps": None}, save_freq=0,
        eval=EvalSettings(eval_freq=0, n_eval_episodes=args.eval_episodes,
                          eval_seed=VALIDATION_SEED, success_kwargs=success_kwargs(data.env_id),
                          stop_success=None),
        device=args.device, torch_threads=args.torch_threads, vec_env="dummy",
        versions=versions(), command="python -m agents.bc " + shlex.join(sys.argv[1:]),
        started=datetime.now(timezone.utc).isoformat(timespec="seconds"),
        env_signature=env_signature(eval_env))
    print(f"behaviour cloning on {args.dataset}: {data.provenance['episodes']} episodes, "
          f"{len(data.observations)} transitions of {data.env_id}", flush=True)
    t0 = time.time()
    best, curve = fit(model, vecnormalize, data, args, eval_env)
    wall = round(time.time() - t0, 1)
    eval_env.close()
    run_dir.joinpath(data.env_id).mkdir(parents=True)
    write_args(run_dir, data.env_id, {
        "algo": "ppo", "seed": args.seed, "conf_file": record.conf_file, "n_timesteps": 0,
        "device": args.device, "num_threads": args.torch_threads, "vec_env": "dummy",
        "eval_freq": 0, "eval_episodes": args.eval_episodes, "save_freq": 0,
        "log_folder": str(args.log_folder)})
    model.save(run_dir / f"{data.env_id}.zip")
    save_vecnormalize(vecnormalize, run_dir / data.env_id / "vecnormalize")
    arrays: dict[str, Any] = {k: np.array([c.get(k, np.nan) for c in curve]) for k in curve[0]}
    np.savez(run_dir / "bc_curve.npz", **arrays)
    record.outcome = BCOutcome(
        dataset=data.provenance,
        fit={"epochs": args.epochs, "batch_size": args.batch_size, "lr": args.lr,
             "net_arch": list(args.net_arch), "eval_every": args.eval_every,
             "loss": "mse of the mean action"},
        wall_time_s=wall, total_timesteps=len(data.observations),
        best_validation={k: (int(v) if k in ("epoch", "n_episodes") else float(v))
                         for k, v in best.items()})
    write_run_config(run_dir, data.env_id, hp, record)
    vecnormalize.close()
    print(f"saved {run_dir / (data.env_id + '.zip')}: validation success "
          f"{summary_success_text(best)} (epoch {int(best['epoch'])}, {wall} s)")
    return run_dir


if __name__ == "__main__":
    run_cli(main)
