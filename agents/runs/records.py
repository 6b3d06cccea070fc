"""Typed run config and run record: what ``agents.train``, ``agents.distill`` and ``agents.bc``
save with a run.

A run's ``<env id>/config.yml`` (:mod:`agents.runs.layout`) is the hyper-parameter entry in
RL Zoo's dialect plus our record under ``softhand``. In memory the pair is a :class:`RunConfig`:
``hyperparams`` stays the YAML entry (a mapping, as RL Zoo reads and writes it; its keys that
the trainers consume are read through typed properties), ``record`` is a :class:`RunRecord`.
:meth:`RunRecord.to_yaml` is the one place the record becomes a mapping again, for
``config.yml``; reading a saved run (:mod:`agents.runs.loading`) keeps the mapping, since runs
of ``rl_zoo3.train`` and older runs carry other or fewer keys.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from agents.common.cli import UserError, check_range


@dataclass
class EvalSettings:
    """Validation during training (``record["eval"]``): every ``eval_freq`` env steps (<= 0:
    never) the ``n_eval_episodes`` goals ``reset(seed=eval_seed + k)`` are played with the
    benchmark's tolerance (``success_kwargs``, env keywords); training stops once the success
    rate reaches ``stop_success`` (None: never)."""

    eval_freq: int
    n_eval_episodes: int
    eval_seed: int
    success_kwargs: dict[str, float]
    stop_success: float | None


#: Ranks of the validated DAgger iterations (the best is kept): ``success`` orders by the
#: success rate, then by the lower median final error; ``strict`` by the success rate, then by
#: the strict success rate (within 0.5 mm / 0.5 deg), then by the median final error; ``safe``
#: by the success rate less the rate of episodes ended by a physical failure, then as strict.
SELECT_RULES = ("success", "strict", "safe")


@dataclass
class DaggerSchedule:
    """The DAgger schedule of ``agents.distill`` (``record["dagger"]``): ``iterations``;
    ``rollout_steps`` control steps per env and iteration; teacher-action probability
    ``beta_decay ** k`` at iteration k; ``epochs`` passes over the data set per iteration in
    minibatches of ``batch_size``, or, with ``updates`` > 0, that many minibatches per
    iteration drawn uniformly from the data set (a fixed cost per iteration however large the
    data set has grown); Adam step size linear from ``lr`` to ``lr_final``; at most
    ``max_samples`` (blind observation, label) pairs, oldest dropped first;
    ``latency_labels``: label with the teacher's action when the command takes effect
    (:class:`agents.distill.DelayedLabels`); ``select``: how validated iterations are ranked
    (:data:`SELECT_RULES`); ``blind_teacher``: the teacher is a blind policy, not a
    privileged one (:func:`agents.distill.rollout_layout`); ``squeeze_expectile``: the
    expectile of the labels' squeeze component the student fits (0.5: the mean, plain squared
    error; below 0.5 closing more than the label costs more than closing less,
    :func:`agents.distill.imitation_loss`). Range-checked on construction (UserError naming the
    command-line flag)."""

    iterations: int = 40
    rollout_steps: int = 50
    beta_decay: float = 0.5
    epochs: int = 2
    updates: int = 0
    batch_size: int = 1024
    lr: float = 1e-3
    lr_final: float = 1e-3
    max_samples: int = 2_000_000
    latency_labels: bool = False
    select: str = "success"
    blind_teacher: bool = False
    squeeze_expectile: float = 0.5

    def __post_init__(self) -> None:
        """Range checks (UserError on a bad value)."""
        if self.select not in SELECT_RULES:
            raise UserError(f"--select must be one of {', '.join(SELECT_RULES)} "
                            f"(got {self.select!r})")
        check_range("--iterations", self.iterations, 1, 10_000)
        check_range("--rollout-steps", self.rollout_steps, 1, 100_000)
        check_range("--beta-decay", self.beta_decay, 0.0, 1.0)
        check_range("--epochs", self.epochs, 1, 1000)
        check_range("--updates", self.updates, 0, 1_000_000)
        check_range("--batch-size", self.batch_size, 1, 1_000_000)
        check_range("--max-samples", self.max_samples, 1, 100_000_000)
        if not 0.0 < self.squeeze_expectile < 1.0:
            raise UserError(f"--squeeze-expectile must be in (0, 1) "
                            f"(got {self.squeeze_expectile!r})")
        for flag, value in (("--lr", self.lr), ("--lr-final", self.lr_final)):
            if not 0.0 < value <= 1.0:
                raise UserError(f"{flag} must be in (0, 1] (got {value!r})")


@dataclass
class RunOutcome:
    """How a run ended (the fields both trainers record): wall time (s) of the training
    loop, env steps done, whether SIGINT or SIGTERM interrupted it
    (:mod:`agents.sb3.interrupts`); ``best_validation``: the best validation summary (None:
    no validation completed)."""

    wall_time_s: float
    total_timesteps: int
    interrupted: bool

    def to_yaml(self) -> dict[str, Any]:
        """The record keys of the outcome (``best_validation`` only when there is one)."""
        out = dataclasses.asdict(self)
        if out.get("best_validation", 0) is None:
            out.pop("best_validation")
        return out


@dataclass
class TrainOutcome(RunOutcome):
    """How an ``agents.train`` run ended (:class:`RunOutcome`), and the env step at which the
    validation success stopped it (None: it did not)."""

    stopped_on_success_at: int | None
    best_validation: dict[str, float] | None = None


@dataclass
class DistillOutcome(RunOutcome):
    """How an ``agents.distill`` run ended (:class:`RunOutcome`; ``best_validation``: the best
    iteration's, None if the run was interrupted before its first validation), the teacher's
    provenance (path, sha256, wall time, steps) and the DAgger schedule."""

    teacher: dict[str, Any]
    dagger: DaggerSchedule
    best_validation: dict[str, float] | None = None
    trainer: str = "dagger"


@dataclass
class RLlibOutcome:
    """How an ``agents.rllib_train`` run ended: wall time (s) of the training iterations, env
    steps sampled, iterations, env steps per second of the iterations, and the Ray and RLlib
    settings (``ray``: address, env runners, envs per runner, CPUs of the cluster, Ray
    version; ``rllib``: the PPO settings as RLlib got them)."""

    wall_time_s: float
    total_timesteps: int
    iterations: int
    env_steps_per_s: float
    ray: dict[str, Any]
    rllib: dict[str, Any]
    trainer: str = "rllib"
    interrupted: bool = False

    def to_yaml(self) -> dict[str, Any]:
        """The record keys of the outcome."""
        return dataclasses.asdict(self)


@dataclass
class BCOutcome:
    """How an ``agents.bc`` run ended: the dataset's provenance (id, episodes, transitions,
    the policy that collected it, its code permalink), the fit (epochs, minibatch, Adam step
    size, network), wall time (s), transitions fitted (``total_timesteps``; no env step is
    trained on) and the best validation summary (its ``epoch`` included)."""

    dataset: dict[str, Any]
    fit: dict[str, Any]
    wall_time_s: float
    total_timesteps: int
    best_validation: dict[str, float]
    trainer: str = "bc"

    def to_yaml(self) -> dict[str, Any]:
        """The record keys of the outcome."""
        return dataclasses.asdict(self)


@dataclass
class RunRecord:
    """Our record of a run (``config.yml``'s ``softhand`` entry).

    Set before training: algorithm, env id, seed, hyper-parameter file, the command-line
    overrides (``env_kwargs``, ``hyperparams``, ``n_timesteps``), checkpoint period (env
    steps), validation settings, torch device and threads, vectorisation, package versions,
    the command and its start time (ISO 8601, UTC); ``fit_threads``: torch threads while the
    networks are fitted between rollouts (None: ``torch_threads`` throughout);
    ``trained_agent``: provenance of the model the run started from (None: fresh weights);
    ``finetune``: the fine-tuning settings of ``agents.train`` (critic warm-up steps and step
    size, the log std set at the start; :mod:`agents.sb3.finetune`; None: none);
    ``env_signature``: the env's signature (``softhand_env.envs.signature``), checked when the
    model is loaded. ``outcome``: set when the run ends.
    """

    algo: str
    env_id: str
    seed: int
    conf_file: str
    overrides: dict[str, Any]
    save_freq: int
    eval: EvalSettings
    device: str
    torch_threads: int
    vec_env: str
    versions: dict[str, str]
    command: str
    started: str
    fit_threads: int | None = None
    trained_agent: dict[str, Any] | None = None
    finetune: dict[str, Any] | None = None
    env_signature: dict[str, Any] | None = None
    outcome: TrainOutcome | DistillOutcome | BCOutcome | RLlibOutcome | None = None

    def to_yaml(self) -> dict[str, Any]:
        """The record as ``config.yml`` holds it (plain YAML values; ``env_signature`` only
        once set, the outcome's keys at the top level)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
               if f.name not in ("eval", "env_signature", "outcome")}
        out["eval"] = dataclasses.asdict(self.eval)
        if self.env_signature is not None:
            out["env_signature"] = self.env_signature
        if self.outcome is not None:
            out.update(self.outcome.to_yaml())
        return out


@dataclass
class RunConfig:
    """A run's configuration: the hyper-parameter entry (RL Zoo's dialect, merged with the
    command-line overrides; the YAML boundary) and our :class:`RunRecord`."""

    hyperparams: dict[str, Any]
    record: RunRecord

    @property
    def n_envs(self) -> int:
        """Training envs."""
        return int(self.hyperparams["n_envs"])

    @property
    def n_timesteps(self) -> int:
        """Env steps to train."""
        return int(self.hyperparams["n_timesteps"])

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """``gym.make`` keywords of the run."""
        kwargs: dict[str, Any] = self.hyperparams["env_kwargs"]
        return kwargs

    @property
    def env_wrapper(self) -> Any:
        """The ``env_wrapper`` entry (None, a dotted path or a list; see
        :func:`agents.common.env_factory.wrapper_list`)."""
        return self.hyperparams.get("env_wrapper")

    @property
    def normalize(self) -> Any:
        """The ``normalize`` entry (false, true or VecNormalize keywords)."""
        return self.hyperparams["normalize"]

    @property
    def policy(self) -> str:
        """The policy name (``MlpPolicy``, ``AsymmetricPolicy``, ...)."""
        return str(self.hyperparams["policy"])
