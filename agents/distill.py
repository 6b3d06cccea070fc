"""Teacher-student distillation (DAgger): a blind student imitates a privileged teacher.

The teacher is a saved PPO run trained with ``privileged_obs=True`` (its policy reads the
blind observation *and* the privileged physics state: object pose and velocity, deformations,
goal error). It sees where the object is, so it can close the loop on the pose. The student is
the policy of an ordinary run config (the ``--conf-file`` entry, e.g. a blind ``MlpPolicy``
with the time feature): it reads only the blind ``observation`` (joint sensing, goal, the
wrappers' features) and learns to act as the teacher would, by DAgger (Ross et al., 2011):

1. roll out ``n_envs`` hands on the native vector env, each step acting with the teacher's
   action with probability ``beta_k = beta_decay ** k`` (iteration k), else the student's;
2. label every visited state with the teacher's deterministic action (from the privileged
   observation of that state) and add (blind observation, label) to the data set;
3. fit the student's mean action to the labels (mean squared error, or with
   ``--squeeze-expectile`` an expectile of the squeeze component,
   :func:`~agents.sb3.imitation.imitation_loss`; Adam, the step size goes linearly from
   ``--lr`` to ``--lr-final``), then validate the
   student alone on the validation goals (``reset(seed=eval_seed + k)``, the benchmark's
   success rule) and keep the best iteration (``--select``: by success rate, then median final
   error; or by success rate, then the strict rate within 0.5 mm / 0.5 deg, then median final
   error; or, ``safe``, by success rate less the rate of episodes ended by a physical failure,
   then as ``strict``).

The student may read more than the teacher's blind observation: a longer history of frames
(``history_len``), the fingertips' tactile entries (``obs_mode: proprio_tactile``) and the
features of further wrappers after the teacher's (e.g. :mod:`agents.wrappers.action_history`).
The teacher then reads its part of each student observation
(:func:`~agents.sb3.imitation.teacher_view`), so a student can learn to infer from the recent
past or its fingertips what the teacher reads in its
privileged observation (e.g. the randomised parameters of the episode).

With ``--blind-teacher`` the teacher is itself a blind policy (a distilled student, e.g. one
that reads its fingertips) and the student may read *less* than it: the rollouts run the union
of both observations (:func:`~agents.sb3.imitation.rollout_layout`) and each policy reads its
own part (:func:`~agents.sb3.imitation.blind_view`), so a student without fingertip sensing
can imitate one with it.

Nothing of the teacher is in the student's inputs or outputs: at play time the student is a
plain blind policy. The result is saved as a run in the layout of :mod:`agents.train` (a PPO
zip whose actor is the student; ``algo: ppo``, ``trainer: dagger`` and the teacher's path and
checksum in the record), so ``agents.evaluate --model <run>`` plays it and ``agents.train``
can fine-tune it. Usage::

    python -m agents.distill --env SoftHandPose-v0 --teacher logs/ppo/SoftHandPose-v0_1 \\
        --conf-file agents/configs/ppo_native.yml --log-folder logs
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.cli import UserError, check_run_location, run_cli
from agents.common.env_factory import make_env, task_targets, wrapper_list
from agents.common.metrics import (
    error_score,
    summary_success_text,
)
from agents.runs.loading import ModelPolicy
from agents.runs.model_files import sha256
from agents.runs.records import SELECT_RULES, DaggerSchedule, DistillOutcome, EvalSettings
from agents.runs.writing import write_args, write_run_config
from agents.sb3.imitation import (
    BLIND_KEY,
    PAIR_KEYS,
    blind_view,
    imitation_loss,
    lr_at,
    rollout_layout,
    teacher_view,
    validate,
    view_layout,
)
from agents.sb3.interrupts import DeferredSignals, Interrupted
from agents.sb3.native_vec_env import make_sb3_vec_env
from agents.sb3.policies import mean_action as student_mean
from agents.sb3.threads import fitting_threads
from agents.sb3.training import (
    TrainSettings,
    build,
    make_parser,
    make_validation_env,
    next_run_dir,
    probe_signature,
    resolve_config,
    start_from,
)
from softhand_env.envs.tasks import REWARD_KWARGS

#: Options of agents.train that DAgger has no use for (refused unless left at their default).
NOT_APPLICABLE = ("--n-timesteps", "--vec-env", "--eval-freq", "--save-freq")


@dataclass
class DistillSettings(TrainSettings):
    """The distillation command line: the training settings (the student's run), the teacher's
    run directory or zip and the DAgger schedule (its fields are the command line's
    ``--iterations`` ... ``--latency-labels``; ``--lr-final`` defaults to ``--lr``)."""

    teacher: str = ""
    dagger: DaggerSchedule = dataclasses.field(default_factory=DaggerSchedule)

    @classmethod
    def from_namespace(cls, ns: argparse.Namespace) -> DistillSettings:
        """The settings of a parsed :func:`make_distill_parser` command line."""
        train_fields = {f.name for f in dataclasses.fields(TrainSettings)}
        schedule = {f.name: getattr(ns, f.name) for f in dataclasses.fields(DaggerSchedule)}
        if schedule["lr_final"] is None:
            schedule["lr_final"] = schedule["lr"]
        return cls(**{name: getattr(ns, name) for name in train_fields}, teacher=ns.teacher,
                   dagger=DaggerSchedule(**schedule))


def make_distill_parser() -> argparse.ArgumentParser:
    """Arguments of ``agents.train`` plus the teacher and the DAgger schedule."""
    p = make_parser("python -m agents.distill", __doc__.split("\n\n")[0])
    p.add_argument("--teacher", required=True,
                   help="run directory (or zip) of a privileged teacher (privileged_obs=True)")
    p.add_argument("--iterations", type=int, default=40, help="DAgger iterations, 1 .. 10000")
    p.add_argument("--rollout-steps", type=int, default=50,
                   help="control steps per env and iteration, 1 .. 100000")
    p.add_argument("--beta-decay", type=float, default=0.5,
                   help="teacher-action probability at iteration k: beta_decay**k, in [0, 1]")
    p.add_argument("--epochs", type=int, default=2,
                   help="passes over the aggregated data per iteration, 1 .. 1000")
    p.add_argument("--updates", type=int, default=0,
                   help="minibatches per iteration drawn uniformly from the aggregated data "
                        "(replaces --epochs, so an iteration costs the same however large the "
                        "data set is), 0 .. 1e6; 0: use --epochs")
    p.add_argument("--batch-size", type=int, default=1024, help="minibatch, 1 .. 1e6")
    p.add_argument("--lr", type=float, default=1e-3, help="Adam step size, (0, 1]")
    p.add_argument("--lr-final", type=float, default=None,
                   help="Adam step size at the last iteration, (0, 1]: the step size goes "
                        "linearly from --lr to it over the iterations (default: --lr, "
                        "constant)")
    p.add_argument("--latency-labels", action="store_true",
                   help="label the states of an episode with set-point latency L with the "
                        "teacher's action L steps later, when the command takes effect")
    p.add_argument("--select", choices=SELECT_RULES, default="success",
                   help="rank of the validated iterations, the best kept: success (success "
                        "rate, then median final error), strict (success rate, then the "
                        "strict rate within 0.5 mm / 0.5 deg, then median final error) or safe "
                        "(success rate minus the rate of episodes ended by a physical failure, "
                        "then as strict)")
    p.add_argument("--squeeze-expectile", type=float, default=0.5,
                   help="fit this expectile of the labels' squeeze component (both fingers "
                        "closing) instead of their mean, in (0, 1): below 0.5 closing more "
                        "than the teacher costs more than closing less (default 0.5: plain "
                        "squared error)")
    p.add_argument("--blind-teacher", action="store_true",
                   help="the teacher is a blind policy (e.g. a distilled student that reads "
                        "its fingertips) instead of a privileged_obs run: the rollouts read "
                        "both observations (the longer history, tactile entries if either "
                        "reads them) and each policy its own")
    p.add_argument("--max-samples", type=int, default=2_000_000,
                   help="data set cap (oldest dropped first), 1 .. 1e8")
    return p


def parse_args(argv: Sequence[str] | None = None) -> DistillSettings:
    """The distillation settings of a command line, range-checked."""
    p = make_distill_parser()
    ns = p.parse_args(argv)
    TrainSettings.from_namespace(ns)  # the training part's checks come first
    for flag in NOT_APPLICABLE:
        dest = flag[2:].replace("-", "_")
        if getattr(ns, dest) != p.get_default(dest):
            raise UserError(f"{flag} does not apply to agents.distill (the student is validated "
                            "after every iteration on the native env; --iterations sets the "
                            "length)")
    return DistillSettings.from_namespace(ns)



def check_pair(teacher: ModelPolicy, env_id: str, hp: dict[str, Any],
               blind_teacher: bool = False) -> tuple[dict[str, Any], dict[str, Any]]:
    """The student's env keywords and the teacher's :data:`VIEW_KEYS` and
    :data:`ACTUATION_KEYS` keywords.

    Checks that the teacher plays the same env (same task, keywords besides
    :data:`VIEW_KEYS`, :data:`ACTUATION_KEYS` and the reward's
    :data:`~softhand_env.envs.tasks.REWARD_KWARGS`, wrappers) with the privileged
    observation and that the student's observation contains the teacher's (at least as many
    frames; tactile entries if the teacher's has them). With
    ``blind_teacher`` the teacher must instead be a blind policy (no ``privileged_obs``) and
    the observations need not contain each other (the rollouts
    read both views, :func:`rollout_layout`). UserError otherwise.
    """
    if teacher.env_id != env_id:
        raise UserError(f"the teacher was trained on {teacher.env_id}, not {env_id}")
    t_kwargs = dict(teacher.env_kwargs)
    privileged = bool(t_kwargs.pop("privileged_obs", False))
    if blind_teacher and privileged:
        raise UserError("--blind-teacher: the teacher must be a blind policy (a distilled "
                        "student), not a run with privileged_obs: true")
    if not blind_teacher and not privileged:
        raise UserError("the teacher must be a run with env_kwargs privileged_obs: true (a "
                        "blind teacher, e.g. a distilled student, needs --blind-teacher)")
    s_kwargs = dict(hp["env_kwargs"])
    if s_kwargs.get("privileged_obs") or s_kwargs.get("goal_obs"):
        raise UserError("the student reads the plain blind observation: leave privileged_obs "
                        "and goal_obs out of its env_kwargs")
    t_view = {key: t_kwargs.pop(key) for key in PAIR_KEYS if key in t_kwargs}
    # the rollouts score nothing: a teacher trained on another reward plays the same task
    same_t, same_s = ({k: v for k, v in kwargs.items()
                       if k not in PAIR_KEYS and k not in REWARD_KWARGS}
                      for kwargs in (t_kwargs, s_kwargs))
    if same_t != same_s:
        raise UserError(f"teacher and student env_kwargs differ (besides privileged_obs, "
                        f"history_len, obs_mode, onset_obs, setpoint_ramp_ms and the reward's "
                        f"keywords): {t_kwargs} vs {s_kwargs}")
    t_layout, s_layout = view_layout(t_view), view_layout(s_kwargs)
    if not blind_teacher and s_layout.history_len < t_layout.history_len:
        raise UserError(f"the student's history_len ({s_layout.history_len}) must be at least "
                        f"the teacher's ({t_layout.history_len})")
    if not blind_teacher and t_layout.tactile and not s_layout.tactile:
        raise UserError("the teacher reads tactile entries (obs_mode proprio_tactile): so must "
                        "the student")
    if not blind_teacher and t_layout.onset and not s_layout.onset:
        raise UserError("the teacher reads the grasp-onset entries (onset_obs: true): so must "
                        "the student")
    t_wrappers = wrapper_list(teacher.env_wrapper)
    if wrapper_list(hp.get("env_wrapper"))[: len(t_wrappers)] != t_wrappers:
        raise UserError("the student's env_wrapper must start with the teacher's (further "
                        "wrappers append features the teacher does not read)")
    if hp.get("normalize") not in (None, False):
        raise UserError("the student learns on raw observations: set normalize: false in its "
                        "entry")
    return s_kwargs, t_view


def iteration_rank(summary: dict[str, float], targets: Sequence[str],
                   select: str) -> tuple[float, ...]:
    """The rank of a validated iteration under ``select`` (larger is better;
    :data:`~agents.runs.records.SELECT_RULES`): (success rate, -error score), (success rate,
    strict success rate, -error score) or (success rate - failure rate, strict success rate,
    -error score)."""
    score = -error_score(summary, targets)
    if select == "safe":
        return (summary["success_rate"] - summary["failure_rate"], summary["success_strict"],
                score)
    if select == "strict":
        return summary["success_rate"], summary["success_strict"], score
    return summary["success_rate"], score


class DelayedLabels:
    """DAgger labels for episodes with a set-point latency (``--latency-labels``).

    With a latency of L control steps the command the student issues at step t is applied from
    step t + L on, so the action the teacher (which assumes no latency) would take *then* is
    the one to imitate: a blind observation of step t is labelled with the teacher's action at
    step t + L of the same episode (dropped if the episode ends first). With L = 0 this is the
    plain DAgger label.

    Parameters
    ----------
    n_envs : int
        Number of environments in the rollout vector env.
    """

    def __init__(self, n_envs: int):
        self._pending: list[tuple[int, int, int, np.ndarray]] = []  # due, env, episode, row
        self._episode = np.zeros(n_envs, dtype=np.int64)
        self._now = 0

    def step(self, blind: np.ndarray, t_act: np.ndarray, latency: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """Record step t: blind observations (N, D), the teacher's actions (N, A) and each
        episode's latency (N,) in control steps; returns the (blind, label) pairs complete at
        this step, shapes (M, D), (M, A). Call :meth:`end_step` after stepping the env."""
        rows, labels, keep = [], [], []
        for due, i, episode, row in self._pending:
            if self._episode[i] != episode:
                continue  # the episode ended before the command took effect
            if due == self._now:
                rows.append(row)
                labels.append(t_act[i])
            else:
                keep.append((due, i, episode, row))
        now = np.asarray(latency) == 0
        for j in np.flatnonzero(~now).tolist():
            keep.append((self._now + int(latency[j]), j, int(self._episode[j]),
                         blind[j].copy()))
        self._pending = keep
        x = np.concatenate([blind[now], np.asarray(rows, dtype=blind.dtype).reshape(
            -1, blind.shape[-1])])
        y = np.concatenate([np.asarray(t_act)[now], np.asarray(labels, dtype=np.float32)
                            .reshape(-1, np.shape(t_act)[-1])])
        return x, y

    def end_step(self, dones: np.ndarray) -> None:
        """Advance one control step; ``dones`` (N,) marks the episodes that ended in it."""
        self._episode[np.asarray(dones, dtype=bool)] += 1
        self._now += 1


def step_latencies(infos: Sequence[dict[str, Any]]) -> np.ndarray:
    """The set-point latency (control steps) of the episode each env took its step in, int64
    (N,), from the step's SB3 infos (``info["setpoint_latency"]``; the info of an episode's
    last step still belongs to it), so any VecEnv of soft-hand envs serves."""
    try:
        return np.array([info["setpoint_latency"] for info in infos], dtype=np.int64)
    except KeyError:
        raise UserError("--latency-labels needs info['setpoint_latency'] in every step's "
                        "info (a soft-hand environment)") from None


def minibatches(n: int, schedule: DaggerSchedule) -> Iterator[Any]:
    """Index tensors (int64, (batch,) or shorter at an epoch's end) of one iteration's
    minibatches over a data set of ``n`` samples: ``schedule.epochs`` shuffled passes, or, with
    ``schedule.updates`` > 0, that many batches drawn uniformly with replacement."""
    import torch

    b = schedule.batch_size
    if schedule.updates > 0:
        for _ in range(schedule.updates):
            yield torch.randint(n, (min(b, n),))
        return
    for _ in range(schedule.epochs):
        perm = torch.randperm(n)
        for start in range(0, n, b):
            yield perm[start:start + b]


@dataclass
class DaggerResult:
    """The outcome of :func:`dagger`: the best iteration's validation summary (None: no
    iteration was validated, the run was interrupted first), the per-iteration curve, the env
    steps of all rollouts and the signal that interrupted the run (None: it ran to its end)."""

    best: dict[str, Any] | None
    curve: list[dict[str, float]]
    env_steps: int
    interrupted: str | None = None


def dagger(model: Any, teacher: ModelPolicy, env_id: str, kwargs: dict[str, Any], wrapper: Any,
           n_envs: int, seed: int, schedule: DaggerSchedule, validation: EvalSettings,
           teacher_kwargs: dict[str, Any], log: Any = print,
           stop: DeferredSignals | None = None, fit_threads: int | None = None) -> DaggerResult:
    """Train ``model``'s actor by DAgger (module doc, ``schedule``); the best iteration's
    weights are loaded back into ``model``.

    ``validation``: the validation goals (``n_eval_episodes`` from ``eval_seed``) and the
    success rate that stops early (``stop_success``; ``eval_freq`` is not used: every
    iteration is validated). ``teacher_kwargs``: the teacher's :data:`VIEW_KEYS` keywords (its
    observation is contained in the student's, ``kwargs``; :func:`check_pair`). ``stop``
    (its handlers installed by the caller, :mod:`agents.sb3.interrupts`) is looked at before
    every env step of the rollouts and the validation and before every minibatch: once it has
    received a signal, the current iteration is abandoned and the best validated iteration
    kept (none validated: ``model`` keeps its current weights, ``best`` is None).
    ``fit_threads``: torch threads of the fit after each rollout (None: the current count,
    which the rollouts and validations use; :mod:`agents.sb3.threads`).
    """
    import torch

    if fit_threads is None:
        fit_threads = torch.get_num_threads()
    rng = np.random.default_rng(seed)
    s_layout = view_layout(kwargs)
    t_layout = view_layout(teacher_kwargs)
    blind_teacher = schedule.blind_teacher
    r_layout = rollout_layout(s_layout, t_layout, blind_teacher)
    t_space = teacher.model.observation_space
    t_size = int((t_space if blind_teacher else t_space[BLIND_KEY]).shape[0])
    s_size = int(model.observation_space.shape[0])
    r_kwargs = {**kwargs, "privileged_obs": True}
    if blind_teacher:
        r_kwargs.update(obs_mode=r_layout.obs_mode, history_len=r_layout.history_len,
                        onset_obs=r_layout.onset)
    venv = make_sb3_vec_env(env_id, n_envs, seed, r_kwargs, "native", env_wrapper=wrapper)
    policy = model.policy
    params = [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters()]
    opt = torch.optim.Adam(params, lr=schedule.lr)
    low = torch.as_tensor(model.action_space.low)
    high = torch.as_tensor(model.action_space.high)
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    targets = task_targets(env_id)
    eval_venv = make_validation_env(env_id, kwargs, wrapper, "native", validation)
    signals = stop if stop is not None else DeferredSignals("distillation")  # never installed
    best: dict[str, Any] | None = None
    best_state: dict[str, Any] | None = None
    curve: list[dict[str, float]] = []
    obs: Any = venv.reset()
    delayed = schedule.latency_labels
    labels, no_latency = DelayedLabels(n_envs), np.zeros(n_envs, dtype=np.int64)
    steps = 0
    interrupted: str | None = None
    t0 = time.time()
    try:
        for k in range(schedule.iterations):
            beta = schedule.beta_decay ** k
            for group in opt.param_groups:
                group["lr"] = lr_at(k, schedule.iterations, schedule.lr, schedule.lr_final)
            for _ in range(schedule.rollout_steps):
                signals.check()
                t_obs: Any = teacher_view(obs, t_layout, r_layout, t_size)
                if blind_teacher:
                    t_obs = t_obs[BLIND_KEY]
                t_act, _ = teacher.model.predict(teacher.normalize(t_obs), deterministic=True)
                blind = blind_view(obs[BLIND_KEY], s_layout, r_layout, s_size).astype(np.float32)
                s_act, _ = model.predict(blind, deterministic=True)
                use_teacher = rng.random(n_envs) < beta
                obs, _, dones, infos = venv.step(np.where(use_teacher[:, None], t_act, s_act))
                latency = step_latencies(infos) if delayed else no_latency
                x, y = labels.step(blind, np.asarray(t_act, dtype=np.float32), latency)
                xs.append(x)
                ys.append(y)
                labels.end_step(dones)
                steps += n_envs
            total = sum(len(x) for x in xs)
            while total - len(xs[0]) >= schedule.max_samples:
                total -= len(xs.pop(0))
                ys.pop(0)
            x_all = torch.as_tensor(np.concatenate(xs))
            y_all = torch.clamp(torch.as_tensor(np.concatenate(ys)), low, high)
            n = len(x_all)
            loss = torch.zeros(())
            with fitting_threads(fit_threads):
                for idx in minibatches(n, schedule):
                    signals.check()
                    loss = imitation_loss(student_mean(policy, x_all[idx]), y_all[idx],
                                          schedule.squeeze_expectile)
                    opt.zero_grad()
                    loss.backward()
                    opt.step()
            summary = validate(model, eval_venv, targets, validation.eval_seed, signals)
            point = {"iteration": k, "env_steps": steps, "wall_s": round(time.time() - t0, 1),
                     "beta": beta, "loss": float(loss.detach()), "samples": n, **summary}
            curve.append(point)
            log(f"iteration {k}: beta {beta:.3f}, loss {point['loss']:.5f}, {n} samples, "
                f"validation success {summary_success_text(summary)}, strict "
                f"{summary['success_strict']:.0%}, failures {summary['failure_rate']:.0%} "
                f"({point['wall_s']} s)")
            rank = iteration_rank(summary, targets, schedule.select)
            if best is None or rank > best["rank"]:
                best = {"rank": rank, "iteration": k, "env_steps": steps, **summary}
                best_state = {key: v.clone() for key, v in policy.state_dict().items()}
            if validation.stop_success is not None and (
                    summary["success_rate"] >= validation.stop_success):
                log(f"validation success >= {validation.stop_success:.0%}: distillation stops")
                break
    except Interrupted as exc:
        interrupted = str(exc)
        log(f"{interrupted}: stopped in iteration {len(curve)} after {steps} env steps; "
            "saving the run")
    venv.close()
    eval_venv.close()
    if best_state is not None:
        policy.load_state_dict(best_state)
    if best is not None:
        best.pop("rank")
    return DaggerResult(best, curve, steps, interrupted)


#: Keys of ``dagger_curve.npz`` besides the validation summary's.
CURVE_KEYS = ("iteration", "env_steps", "wall_s", "beta", "loss", "samples")


def save_curve(curve: Sequence[dict[str, float]], path: Path) -> None:
    """``dagger_curve.npz``: one array (K,) per key of the K iterations' points (an
    interrupted run without a validated iteration: the :data:`CURVE_KEYS` and
    ``success_rate``, empty)."""
    keys = list(curve[0]) if curve else [*CURVE_KEYS, "success_rate"]
    arrays: dict[str, Any] = {key: np.array([p[key] for p in curve]) for key in keys}
    np.savez(path, **arrays)


def main(argv: Sequence[str] | None = None) -> Path:
    """CLI entry point; returns the run directory of the student.

    Every input is checked (output location, teacher and student, envs, policy built) before
    the run directory is created. From its creation on, SIGINT and SIGTERM stop the
    distillation at the next env step or minibatch (:mod:`agents.sb3.interrupts`): the best
    validated iteration (none yet: the current weights) is saved as the run's model and
    ``config.yml`` is finalised with ``interrupted: true``.
    """
    args = parse_args(argv)
    if args.algo != "ppo":
        raise UserError("the student is saved as a PPO policy: use --algo ppo")
    check_run_location(args.log_folder)
    planned = next_run_dir(Path(args.log_folder), "ppo", args.env, args.run_name)
    if planned.exists():
        raise UserError(f"run directory {planned} exists (choose another --run-name)")
    config = resolve_config(args, command="agents.distill")
    hp, rec = config.hyperparams, config.record
    teacher = ModelPolicy(args.teacher)
    kwargs, teacher_kwargs = check_pair(teacher, args.env, hp, args.dagger.blind_teacher)
    wrapper = config.env_wrapper
    rec.env_signature = probe_signature(args.env, kwargs, wrapper, args.seed)
    plain = {k: v for k, v in kwargs.items() if k not in PAIR_KEYS}
    privileged = {} if args.dagger.blind_teacher else {"privileged_obs": True}
    teacher_env = make_env(args.env, {**plain, **teacher_kwargs, **privileged},
                           teacher.env_wrapper)  # the spaces of the teacher's view
    teacher.check_env(teacher_env)
    teacher_env.close()
    model, eval_env = build(config, verbose=0)
    eval_env.close()
    model.get_env().close()
    if args.trained_agent is not None:
        start_from(model, args.trained_agent, rec)
    run_dir = next_run_dir(Path(args.log_folder), "ppo", args.env, args.run_name)
    if run_dir.exists():
        raise UserError(f"run directory {run_dir} exists (choose another --run-name)")
    schedule = args.dagger
    stop = DeferredSignals("distillation")
    with stop.installed():
        (run_dir / args.env).mkdir(parents=True)
        write_args(run_dir, args.env, {
            "algo": "ppo", "seed": args.seed, "conf_file": rec.conf_file, "n_timesteps": 0,
            "device": args.device, "num_threads": args.torch_threads, "vec_env": "native",
            "eval_freq": 0, "eval_episodes": args.eval_episodes, "save_freq": 0,
            "log_folder": str(args.log_folder)})
        write_run_config(run_dir, args.env, hp, rec)  # rewritten at the end (results, sha256)
        print(f"run directory: {run_dir}", flush=True)
        t0 = time.time()
        result = dagger(model, teacher, args.env, kwargs, wrapper, config.n_envs, args.seed,
                        schedule, rec.eval, teacher_kwargs,
                        log=lambda line: print(line, flush=True), stop=stop,
                        fit_threads=rec.fit_threads)
        wall = round(time.time() - t0, 1)
        model.save(run_dir / f"{args.env}.zip")  # the best iteration's weights (dagger())
        save_curve(result.curve, run_dir / "dagger_curve.npz")
        best = result.best
        rec.outcome = DistillOutcome(
            teacher={"path": str(teacher.path), "sha256": sha256(teacher.path),
                     "wall_time_s": teacher.run.record.get("wall_time_s"),
                     "total_timesteps": teacher.run.record.get("total_timesteps")},
            dagger=schedule,
            wall_time_s=wall, total_timesteps=result.env_steps,
            interrupted=result.interrupted is not None,
            best_validation=None if best is None else {
                key: (float(v) if key != "iteration" else int(v)) for key, v in best.items()},
        )
        write_run_config(run_dir, args.env, hp, rec)
    what = (f"interrupted ({result.interrupted}), saved" if result.interrupted is not None
            else "saved")
    if best is None:
        print(f"{what} {run_dir / (args.env + '.zip')}: no iteration validated, the current "
              f"weights ({wall} s)")
    else:
        print(f"{what} {run_dir / (args.env + '.zip')}: validation success "
              f"{summary_success_text(best)} (iteration {best['iteration']}, {wall} s)")
    return run_dir


if __name__ == "__main__":
    run_cli(main)
