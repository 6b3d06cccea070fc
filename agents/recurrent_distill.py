"""A recurrent student by DAgger: a GRU policy that reads one frame per control step and
carries what it inferred (the hand's hidden parameters, where the object lies) in its state.

A research prototype beside :mod:`agents.distill`, validation only: the student is written as
a torch state dict with a small YAML record, not as an SB3 run, so ``agents.evaluate`` cannot
play it and it is never scored on the test goals here (validation goals below
``reset(seed=10000)`` only). ``--play RUN`` re-validates a saved student on other
validation goals.

The DAgger loop is :mod:`agents.distill`'s with a blind teacher (a saved blind policy, e.g.
the shipped fingertip student): the rollouts run the union of both observations and each
policy reads its own part (:func:`~agents.sb3.imitation.blind_view`); with probability
``0.5 ** k`` (iteration k) an env steps with the teacher's action, else the student's; every
visited state is labelled with the teacher's deterministic action. The student's state is
cleared at each episode's start, and it is fitted on whole episodes (back-propagation through
time over up to ``max_episode_steps`` steps, masked where an episode ended early) with
:func:`~agents.sb3.imitation.imitation_loss`. Every ``--eval-every`` iterations the student is
validated alone (the benchmark's success rule, :func:`~agents.sb3.imitation.validate`) and
the best iteration is kept (``--select``). Usage::

    python -m agents.recurrent_distill --teacher SoftHandPoseRandom-v1 \\
        --env-kwargs obs_mode:proprio history_len:1 onset_obs:true setpoint_ramp_ms:80 \\
        --out logs/gru_student
    python -m agents.recurrent_distill --play logs/gru_student --eval-episodes 500 \\
        --eval-seed 5600

Outputs in ``--out`` (refused if it exists): ``student.pt`` (state dict of the kept
iteration; loaded with ``weights_only=True``), ``student.yml`` (env id and keywords, wrappers,
sizes, teacher path and checksum, schedule, the validation curve and the kept iteration's
summary).
"""

from __future__ import annotations

import argparse
import pickle
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from agents.common.cli import ArgumentParser, UserError, check_range, parse_kv, run_cli
from agents.common.env_factory import check_env_id, task_targets
from agents.common.metrics import success_kwargs, summary_success_text
from agents.play.test_scores import TEST_SEED
from agents.runs.loading import ModelPolicy
from agents.runs.model_files import sha256
from agents.runs.records import EvalSettings
from agents.sb3 import imitation
from agents.sb3.interrupts import DeferredSignals, Interrupted
from agents.sb3.native_vec_env import make_sb3_vec_env
from agents.sb3.training import make_validation_env

#: Largest ``student.yml`` read by ``--play`` (bytes).
MAX_RECORD_BYTES = 1_000_000


def build_student(d_in: int, hidden: int) -> Any:
    """The GRU student: input layer (``d_in`` -> ``hidden``, tanh), a GRU of ``hidden`` units,
    and a head reading the GRU output and the input layer's (2 ``hidden`` -> ``hidden``, tanh,
    -> 2 actions). ``forward(x (B, T, d_in), h (1, B, hidden) or None)`` returns the mean
    actions (B, T, 2) (normalised action space, unclipped) and the last state."""
    import torch
    from torch import nn

    class GRUStudent(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.hidden = hidden
            self.inp = nn.Sequential(nn.Linear(d_in, hidden), nn.Tanh())
            self.gru = nn.GRU(hidden, hidden, batch_first=True)
            self.head = nn.Sequential(nn.Linear(2 * hidden, hidden), nn.Tanh(),
                                      nn.Linear(hidden, 2))

        def forward(self, x: Any, h: Any = None) -> tuple[Any, Any]:
            z = self.inp(x)
            y, h = self.gru(z, h)
            return self.head(torch.cat([y, z], dim=-1)), h

    return GRUStudent()


class RecurrentPlayer:
    """The student acting on N envs one step at a time (``predict``, as
    :func:`~agents.sb3.imitation.validate` calls it), its state (1, N, hidden) cleared by
    :meth:`clear` (all envs, or the rows given: episodes that start)."""

    def __init__(self, net: Any, n_envs: int):
        self.net, self.n_envs = net, n_envs
        self.clear()

    def clear(self, rows: np.ndarray | None = None) -> None:
        import torch

        if rows is None:
            self.state = torch.zeros(1, self.n_envs, self.net.hidden)
        else:
            self.state[:, rows] = 0.0

    def act(self, x: np.ndarray) -> np.ndarray:
        """Actions (N, 2) in [-1, 1] for the observations ``x`` (N, d_in) of one step."""
        import torch

        with torch.no_grad():
            y, self.state = self.net(torch.as_tensor(x, dtype=torch.float32)[:, None],
                                     self.state)
        return np.clip(y[:, 0].numpy(), -1.0, 1.0)

    def predict(self, obs: Any, deterministic: bool = True) -> tuple[np.ndarray, None]:
        return self.act(obs[imitation.BLIND_KEY] if isinstance(obs, dict) else obs), None


def episode_batch(xs: Sequence[np.ndarray], ys: Sequence[np.ndarray]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Episodes of T_i steps (``xs[i]`` (T_i, D), ``ys[i]`` (T_i, 2)) padded to the longest:
    inputs (B, T, D), labels (B, T, 2) (float32) and the mask of real steps (B, T) bool."""
    t = max(len(x) for x in xs)
    x_out = np.zeros((len(xs), t, xs[0].shape[-1]), np.float32)
    y_out = np.zeros((len(xs), t, 2), np.float32)
    mask = np.zeros((len(xs), t), bool)
    for b, (x, y) in enumerate(zip(xs, ys, strict=True)):
        x_out[b, : len(x)], y_out[b, : len(x)], mask[b, : len(x)] = x, y, True
    return x_out, y_out, mask


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = ArgumentParser(prog="python -m agents.recurrent_distill",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--teacher", help="blind teacher: a shipped model name or a run directory")
    p.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY:VALUE",
                   help="the student's keywords apart from the teacher's: "
                        + ", ".join(imitation.PAIR_KEYS))
    p.add_argument("--out", help="output directory (must not exist)")
    p.add_argument("--play", metavar="RUN", help="re-validate the student saved in RUN")
    p.add_argument("--iterations", type=int, default=60)
    p.add_argument("--n-envs", type=int, default=256, help="rollout envs")
    p.add_argument("--updates", type=int, default=150, help="minibatches per iteration")
    p.add_argument("--batch-episodes", type=int, default=64, help="episodes per minibatch")
    p.add_argument("--hidden", type=int, default=128, help="GRU units")
    p.add_argument("--lr", type=float, default=1e-3, help="Adam step size at iteration 0")
    p.add_argument("--lr-final", type=float, default=1e-4, help="... at the last iteration")
    p.add_argument("--squeeze-expectile", type=float, default=0.5,
                   help="expectile of the squeeze component (0.5: mean squared error)")
    p.add_argument("--eval-every", type=int, default=5, help="validate every K iterations")
    p.add_argument("--eval-episodes", type=int, default=200)
    p.add_argument("--eval-seed", type=int, default=5000, help="first validation goal seed")
    p.add_argument("--select", choices=("success", "strict"), default="success",
                   help="keep the iteration of the highest success rate, ties by the strict "
                        "rate (success), or by the strict rate first (strict)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    a = p.parse_args(argv)
    check_range("--iterations", a.iterations, 1, 10_000)
    check_range("--n-envs", a.n_envs, 1, 4096)
    check_range("--updates", a.updates, 1, 100_000)
    check_range("--batch-episodes", a.batch_episodes, 1, 4096)
    check_range("--hidden", a.hidden, 8, 1024)
    check_range("--lr", a.lr, 1e-7, 1.0)
    check_range("--lr-final", a.lr_final, 1e-7, 1.0)
    check_range("--squeeze-expectile", a.squeeze_expectile, 0.01, 0.99)
    check_range("--eval-every", a.eval_every, 1, 10_000)
    check_range("--eval-episodes", a.eval_episodes, 1, 10_000)
    check_range("--eval-seed", a.eval_seed, 0, TEST_SEED - a.eval_episodes)
    check_range("--seed", a.seed, 0, 2**31 - 1)
    check_range("--threads", a.threads, 1, 64)
    if (a.play is None) == (a.teacher is None):
        raise UserError("give --teacher (train a student) or --play RUN (re-validate one)")
    if a.teacher is not None and a.out is None:
        raise UserError("--teacher needs --out")
    return a


def student_kwargs(teacher: ModelPolicy, items: Sequence[str]) -> dict[str, Any]:
    """The student's env keywords: the teacher's, with ``items`` (``key:value``, keys of
    :data:`~agents.sb3.imitation.PAIR_KEYS`) applied."""
    extra = parse_kv(list(items), "--env-kwargs")
    unknown = sorted(set(extra) - set(imitation.PAIR_KEYS))
    if unknown:
        raise UserError("--env-kwargs: the student may set only "
                        f"{', '.join(imitation.PAIR_KEYS)} (got {', '.join(unknown)})")
    return {**teacher.env_kwargs, **extra}


def fit_iteration(net: Any, opt: Any, xs: Sequence[np.ndarray], ys: Sequence[np.ndarray],
                  a: argparse.Namespace, rng: np.random.Generator,
                  stop: DeferredSignals | None = None) -> float:
    """``a.updates`` Adam steps on minibatches of ``a.batch_episodes`` whole episodes drawn
    with replacement (``stop`` checked before each); returns the last loss."""
    import torch

    loss = torch.zeros(())
    for _ in range(a.updates):
        if stop is not None:
            stop.check()
        idx = rng.integers(len(xs), size=min(a.batch_episodes, len(xs)))
        x, y, mask = episode_batch([xs[j] for j in idx], [ys[j] for j in idx])
        pred, _ = net(torch.as_tensor(x))
        m = torch.as_tensor(mask)
        loss = imitation.imitation_loss(pred[m], torch.as_tensor(y)[m], a.squeeze_expectile)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
    return float(loss.detach())


def train(a: argparse.Namespace) -> dict[str, Any]:
    """DAgger of a GRU student (module doc); writes ``--out``, returns the record."""
    import torch
    import yaml

    out = Path(a.out)
    if out.exists():
        raise UserError(f"--out {out} exists")
    teacher = ModelPolicy(a.teacher)
    env_id = teacher.env_id
    t_kwargs = teacher.env_kwargs
    s_kwargs = student_kwargs(teacher, a.env_kwargs)
    s_layout, t_layout = imitation.view_layout(s_kwargs), imitation.view_layout(t_kwargs)
    r_layout = imitation.rollout_layout(s_layout, t_layout, True)
    r_kwargs = {**s_kwargs, "privileged_obs": True, "obs_mode": r_layout.obs_mode,
                "history_len": r_layout.history_len, "onset_obs": r_layout.onset}
    wrapper = teacher.env_wrapper
    if not isinstance(teacher.model.observation_space, gym.spaces.Box):
        raise UserError("the teacher must be a blind policy (a Box observation, not the "
                        "privileged Dict one)")
    venv = make_sb3_vec_env(env_id, a.n_envs, a.seed, r_kwargs, "native", env_wrapper=wrapper)
    t_size = int(teacher.model.observation_space.shape[0])
    eval_env = make_validation_env(env_id, s_kwargs, wrapper, "native", EvalSettings(
        0, a.eval_episodes, a.eval_seed, success_kwargs(env_id), None))
    d_in = int(eval_env.observation_space.shape[0])
    torch.manual_seed(a.seed)
    rng = np.random.default_rng(a.seed)
    net = build_student(d_in, a.hidden)
    opt = torch.optim.Adam(net.parameters(), lr=a.lr)
    player = RecurrentPlayer(net, a.n_envs)
    targets = task_targets(env_id)
    steps = int(s_kwargs.get("max_episode_steps", 50))
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    open_x: list[list[np.ndarray]] = [[] for _ in range(a.n_envs)]
    open_y: list[list[np.ndarray]] = [[] for _ in range(a.n_envs)]
    curve: list[dict[str, Any]] = []
    best: tuple[tuple[float, ...], dict[str, Any], dict[str, Any]] | None = None
    t0 = time.time()
    obs: Any = venv.reset()
    stop = DeferredSignals("recurrent distillation")
    interrupted: str | None = None
    with stop.installed():
        try:
            for k in range(a.iterations):
                obs, best = _iteration(k, a, stop, net, opt, player, teacher, venv, obs,
                                       eval_env, (s_layout, t_layout, r_layout), t_size,
                                       targets, steps, (xs, ys, open_x, open_y), rng, curve,
                                       best, t0)
        except Interrupted as exc:
            interrupted = str(exc)
            print(f"{interrupted}: stopped in iteration {len(curve)}; saving the student",
                  flush=True)
    venv.close()
    eval_env.close()
    out.mkdir(parents=True)
    kept = best[2] if best is not None else net.state_dict()  # none validated: current
    torch.save(kept, out / "student.pt")
    record = {
        "env_id": env_id, "env_kwargs": s_kwargs, "env_wrapper": wrapper, "d_in": d_in,
        "hidden": a.hidden,
        "teacher": {"path": str(teacher.path), "sha256": sha256(teacher.path)},
        "schedule": {key: getattr(a, key) for key in (
            "iterations", "n_envs", "updates", "batch_episodes", "lr", "lr_final",
            "squeeze_expectile", "eval_every", "eval_episodes", "eval_seed", "select", "seed")},
        "wall_time_s": round(time.time() - t0, 1),
        "interrupted": interrupted is not None,
        "best_validation": None if best is None else {
            key: float(v) for key, v in best[1].items()},
        "curve": curve,
    }
    (out / "student.yml").write_text(yaml.safe_dump(record, sort_keys=False))
    if best is None:
        print(f"saved {out / 'student.pt'}: no iteration validated, the current weights",
              flush=True)
    else:
        print(f"saved {out / 'student.pt'}: iteration {best[1]['iteration']}, validation "
              f"success {summary_success_text(best[1])}, strict "
              f"{best[1]['success_strict']:.1%} ({record['wall_time_s']} s)", flush=True)
    return record


def _iteration(k: int, a: argparse.Namespace, stop: DeferredSignals, net: Any, opt: Any,
               player: RecurrentPlayer, teacher: ModelPolicy, venv: Any, obs: Any,
               eval_env: Any, layouts: tuple[Any, Any, Any], t_size: int,
               targets: Sequence[str], steps: int, data: tuple[list[Any], ...],
               rng: np.random.Generator, curve: list[dict[str, Any]], best: Any,
               t0: float) -> tuple[Any, Any]:
    """Iteration ``k`` of :func:`train`: a rollout of ``steps`` control steps on every env
    (episodes completed into ``data``), the fit, every ``a.eval_every`` iterations the
    validation; appends its point to ``curve``; returns the next observation and the best
    validated iteration ``(rank, summary, weights)`` (None: none yet)."""

    s_layout, t_layout, r_layout = layouts
    xs, ys, open_x, open_y = data
    for group in opt.param_groups:
        group["lr"] = imitation.lr_at(k, a.iterations, a.lr, a.lr_final)
    for _ in range(steps):
        stop.check()
        t_obs = imitation.teacher_view(obs, t_layout, r_layout, t_size)[imitation.BLIND_KEY]
        t_act, _ = teacher.model.predict(teacher.normalize(t_obs), deterministic=True)
        x = imitation.blind_view(obs[imitation.BLIND_KEY], s_layout, r_layout, None)
        x = x.astype(np.float32)
        s_act = player.act(x)
        use_teacher = rng.random(a.n_envs) < 0.5 ** k
        obs, _, dones, _ = venv.step(np.where(use_teacher[:, None], t_act, s_act))
        label = np.clip(np.asarray(t_act, dtype=np.float32), -1.0, 1.0)
        for i in range(a.n_envs):
            open_x[i].append(x[i])
            open_y[i].append(label[i])
            if dones[i]:
                xs.append(np.stack(open_x[i]))
                ys.append(np.stack(open_y[i]))
                open_x[i], open_y[i] = [], []
        if dones.any():
            player.clear(np.flatnonzero(dones))
    loss = fit_iteration(net, opt, xs, ys, a, rng, stop)
    point: dict[str, Any] = {"iteration": k, "episodes": len(xs), "loss": loss,
                             "wall_s": round(time.time() - t0, 1)}
    if (k + 1) % a.eval_every == 0 or k == a.iterations - 1:
        summary = imitation.validate(RecurrentPlayer(net, a.eval_episodes), eval_env,
                                     targets, a.eval_seed, stop)
        point.update(success_rate=summary["success_rate"],
                     success_strict=summary["success_strict"],
                     failure_rate=summary["failure_rate"])
        rank = ((summary["success_rate"], summary["success_strict"]) if a.select == "success"
                else (summary["success_strict"], summary["success_rate"]))
        if best is None or rank > best[0]:
            best = (rank, {**summary, "iteration": k},
                    {key: v.clone() for key, v in net.state_dict().items()})
    curve.append(point)
    print(" ".join(f"{key} {v:.4g}" if isinstance(v, float) else f"{key} {v}"
                   for key, v in point.items()), flush=True)
    return obs, best


def load_student(run: Path) -> tuple[Any, dict[str, Any]]:
    """The student saved in ``run`` and its record, executing nothing from the files
    (``yaml.safe_load`` of a bounded file, ``torch.load(weights_only=True)``)."""
    import torch
    import yaml

    record_path, weights = run / "student.yml", run / "student.pt"
    for path in (record_path, weights):
        if not path.is_file():
            raise UserError(f"--play: {path} not found")
    if record_path.stat().st_size > MAX_RECORD_BYTES:
        raise UserError(f"--play: {record_path} is larger than {MAX_RECORD_BYTES} bytes")
    try:
        record = yaml.safe_load(record_path.read_text())
    except yaml.YAMLError as exc:
        raise UserError(f"--play: {record_path} is not plain YAML: {exc}") from None
    if not isinstance(record, dict) or not {"env_id", "env_kwargs", "d_in", "hidden"} <= set(
            record) or not isinstance(record["env_kwargs"], dict) or not isinstance(
            record["env_id"], str):
        raise UserError(f"--play: {record_path} is not a student record")
    check_env_id(record["env_id"])
    d_in, hidden = record["d_in"], record["hidden"]
    if not (isinstance(d_in, int) and 1 <= d_in <= 10_000 and isinstance(hidden, int)
            and 8 <= hidden <= 1024):
        raise UserError(f"--play: {record_path}: d_in or hidden out of range")
    net = build_student(d_in, hidden)
    try:
        net.load_state_dict(torch.load(weights, weights_only=True))
    except (RuntimeError, ValueError, KeyError, EOFError, pickle.UnpicklingError) as exc:
        raise UserError(f"--play: {weights} does not fit the record: {exc}") from None
    return net, record


def play(a: argparse.Namespace) -> dict[str, float]:
    """Validate the student saved in ``a.play`` on ``a.eval_episodes`` goals from
    ``a.eval_seed``."""
    net, record = load_student(Path(a.play))
    env_id = record["env_id"]
    env = make_validation_env(env_id, record["env_kwargs"], record.get("env_wrapper"),
                              "native", EvalSettings(0, a.eval_episodes, a.eval_seed,
                                                     success_kwargs(env_id), None))
    if int(env.observation_space.shape[0]) != record["d_in"]:
        raise UserError("--play: the record's env does not give the student's input size")
    summary = imitation.validate(RecurrentPlayer(net, a.eval_episodes), env,
                                 task_targets(env_id), a.eval_seed)
    env.close()
    print(f"{a.eval_episodes} validation goals from seed {a.eval_seed}: success "
          f"{summary_success_text(summary)}, strict {summary['success_strict']:.1%}, "
          f"failures {summary['failure_rate']:.1%}", flush=True)
    return summary


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """CLI entry point: trains a student (returns its record) or, with ``--play``,
    re-validates one (returns the validation summary)."""
    import torch

    a = parse_args(argv)
    torch.set_num_threads(a.threads)
    return play(a) if a.play is not None else train(a)


if __name__ == "__main__":
    run_cli(main)
