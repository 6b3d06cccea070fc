"""The policy and env of a ``--model`` / ``--policy`` choice (``agents.evaluate``,
``agents.pose_figures``).

:class:`PolicyChoice` names a saved model or a scripted policy; :func:`build` gives the policy
(with the scripted ``predict`` API), the env id, the ``gym.make`` keywords (the run's, or those
the scripted policy declares, with the benchmark's 1 mm / 1 deg success tolerance) and wrappers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from agents.common.cli import UserError
from agents.common.env_factory import make_env, task_targets
from agents.common.metrics import success_kwargs
from agents.runs.loading import ModelPolicy

#: Scripted policies a choice may name.
SCRIPTED = ("paper", "handling", "model-based", "loop-plan")


@dataclass(frozen=True)
class PolicyChoice:
    """A saved model (``model``: shipped name, run directory or zip) or a scripted policy
    (``policy``, one of :data:`SCRIPTED`), exactly one of the two; ``env``: the env id (a
    model's own by default, ``SoftHand-v0`` for ``paper`` / ``handling``; the goal policies
    need one); ``grasp_deg``: the grasp angle (deg) of ``handling``; ``device`` and
    ``trust_model``: how a model is loaded (:class:`~agents.runs.loading.ModelPolicy`);
    ``task_kwargs``: task keywords the user sets on purpose (the evaluation is then not the
    benchmark; see :mod:`agents.runs.task_keywords`). Without them a model is played on its
    id's task: its config's agent keywords only (a config that sets a task keyword otherwise
    than the id is refused). ``allow_off_signature``: a model may be played on ``env``,
    another id of its task (e.g. its ``-v1`` id), and on an env whose signature differs from
    its run's (:meth:`~agents.runs.loading.ModelPolicy.check_env`): an off-signature
    evaluation, not the benchmark's."""

    model: str | None = None
    policy: str | None = None
    env: str | None = None
    grasp_deg: float = 6.0
    device: str = "cpu"
    trust_model: bool = False
    task_kwargs: dict[str, Any] = field(default_factory=dict)
    allow_off_signature: bool = False

    def __post_init__(self) -> None:
        if (self.model is None) == (self.policy is None):
            raise UserError("choose a saved model or a scripted policy (one of the two)")
        if self.policy is not None and self.policy not in SCRIPTED:
            raise UserError(f"unknown scripted policy {self.policy!r} ({', '.join(SCRIPTED)})")


def build(choice: PolicyChoice) -> tuple[Any, str, dict[str, Any], Any, str]:
    """Policy, env id, ``gym.make`` keywords, env wrappers and a short name for the output."""
    if choice.model is not None:
        policy: Any = ModelPolicy(choice.model, device=choice.device,
                                  trust_model=choice.trust_model)
        env_id, wrapper = choice.env or policy.env_id, policy.env_wrapper
        if env_id != policy.env_id and not choice.allow_off_signature:
            raise UserError(f"the model was trained on {policy.env_id}, not {env_id} (pass "
                            "--allow-off-signature to play it there, labelled not the "
                            "benchmark)")
        task_targets(env_id)  # a registered soft-hand id, before the keywords are looked up
        kwargs, _ = policy.evaluation_kwargs(choice.task_kwargs, env_id=env_id)
        name = f"{policy.algo}"
    else:
        from agents.scripted import HandlingProcessPolicy, ModelBasedPolicy, PaperSequencePolicy

        goal_policy = choice.policy in ("model-based", "loop-plan")
        chosen = choice.env or (None if goal_policy else "SoftHand-v0")
        if chosen is None:
            raise UserError(f"--policy {choice.policy} needs --env (a goal task)")
        env_id = chosen
        if choice.policy == "paper":
            policy = PaperSequencePolicy()
        elif choice.policy == "handling":
            policy = HandlingProcessPolicy(choice.grasp_deg)
        else:
            from agents.scripted.loop_plan import LoopPlanPolicy

            if choice.policy == "loop-plan" and task_targets(env_id) != ("x", "theta"):
                raise UserError(f"--policy loop-plan needs SoftHandPose-v0, not {env_id}")
            if not task_targets(env_id):
                raise UserError(f"--policy {choice.policy} needs a goal task, not {env_id}")
            cls = ModelBasedPolicy if choice.policy == "model-based" else LoopPlanPolicy
            probe = make_env(env_id, cls.env_kwargs)
            policy = cls.from_env(probe)
            probe.close()
        kwargs, wrapper = dict(policy.env_kwargs), None
        if policy.episode_steps is not None:
            kwargs["max_episode_steps"] = policy.episode_steps
        name = str(choice.policy)
    kwargs.update(success_kwargs(env_id))  # benchmark tolerance, whatever the training
    if choice.policy is not None and choice.task_kwargs:
        from agents.runs.task_keywords import evaluation_kwargs

        evaluation_kwargs(env_id, {}, choice.task_kwargs)  # task keywords only, in range
    kwargs.update(choice.task_kwargs)  # the user's, on purpose (labelled not the benchmark)
    return policy, env_id, kwargs, wrapper, name
