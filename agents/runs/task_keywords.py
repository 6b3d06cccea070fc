"""Which env keywords of a saved run are the agent's, and which the benchmark's.

A registered id defines a benchmark task; a model is evaluated on that task, whatever its
``config.yml`` says. Every ``gym.make`` keyword (:data:`softhand_env.envs.options.KEYWORDS`
plus the Dict-observation flags) is in exactly one class:

* :data:`AGENT_KEYS`: the agent's choices, kept from the model's config: its control period
  (``control_dt``), action mapping (``action_mode``, ``normalize_action``, ``max_delta_deg``,
  ``joint_range_deg``, ``setpoint_ramp_ms``) and observation layout (``obs_mode``,
  ``history_len``, ``goal_obs``, ``privileged_obs``). The benchmark's physical checks do not
  depend on them.
* :data:`REWARD_KEYS`: the reward shaping of training (error scales, weights). It does not
  change success or the final errors; at evaluation the registered id's reward is used and the
  model's values are dropped.
* :data:`VIEWER_KEYS`: rendering; never taken from a model's config (refused there).
* every other keyword (:data:`TASK_KEYS`): the task: goal ranges, tolerances, episode length,
  termination, grasp and reset, hand and ``hand_overrides``, randomisation (``rand_*``,
  ``randomize``), sensor model (``obs_noise``, ``setpoint_latency``). They come from the
  registered id. A model config whose value differs from the id's is refused
  (:func:`evaluation_kwargs`, one line naming the keys), unless the user overrides those keys
  on the command line; the evaluation is then not the benchmark and says so.

The episode length is a duration: the id's ``max_episode_steps`` at the default control
period (:data:`DEFAULT_DT`), so a model with a longer control period gets
``floor(duration / control_dt)`` steps (:func:`benchmark_steps`); a config's
``max_episode_steps`` must equal that.
"""

from __future__ import annotations

import math
from typing import Any

from agents.common.cli import UserError
from agents.common.env_factory import short_repr

#: The agent's keywords (kept from a model's config).
AGENT_KEYS = ("control_dt", "action_mode", "normalize_action", "max_delta_deg",
              "joint_range_deg", "setpoint_ramp_ms", "obs_mode", "history_len", "onset_obs",
              "goal_obs", "privileged_obs")
#: Reward shaping of training (replaced by the registered id's at evaluation).
REWARD_KEYS = ("x_scale_mm", "theta_scale_deg", "goal_weight", "success_weight",
               "ctrl_weight", "failure_weight")
#: Rendering (never from a model's config).
VIEWER_KEYS = ("render_mode", "render_width", "render_height")
#: Longest episode (steps) any id or override may ask for.
MAX_EPISODE_STEPS = 1_000_000


def _all_keywords() -> tuple[str, ...]:
    from softhand_env.envs.options import KEYWORDS

    return (*KEYWORDS, "goal_obs", "privileged_obs", "max_episode_steps")


def task_keys() -> tuple[str, ...]:
    """The task's keywords: every keyword not in :data:`AGENT_KEYS`, :data:`REWARD_KEYS` or
    :data:`VIEWER_KEYS` (``max_episode_steps`` included)."""
    other = set(AGENT_KEYS) | set(REWARD_KEYS) | set(VIEWER_KEYS)
    return tuple(k for k in _all_keywords() if k not in other)


def default_dt() -> float:
    """The control period (s) at which the ids' ``max_episode_steps`` are counted."""
    from softhand_env.envs.options import EnvOptions

    return float(EnvOptions().control_dt)


def benchmark_values(env_id: str) -> dict[str, Any]:
    """The task keywords of a registered soft-hand id as its evaluation uses them: the id's
    ``gym.make`` keywords, then its task YAML (goal ranges, tolerances, ...), then the
    keywords' defaults; ``max_episode_steps`` at :func:`default_dt`."""
    import dataclasses

    import gymnasium as gym

    from softhand_env.envs.options import EnvOptions
    from softhand_env.envs.task_configs import load_task_config

    spec = gym.spec(env_id)
    kwargs = dict(spec.kwargs)
    yaml_values = load_task_config(str(kwargs.get("task", "none")))
    out: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(EnvOptions)}
    out.update({"goal_obs": False, "privileged_obs": False})
    out.update({k: v for k, v in yaml_values.items() if k in out})
    out.update({k: v for k, v in kwargs.items() if k in out})
    out["max_episode_steps"] = int(spec.max_episode_steps or yaml_values["max_episode_steps"])
    return {k: out[k] for k in task_keys()}


def benchmark_steps(env_id: str, control_dt: float) -> int:
    """Episode length (steps) of ``env_id``'s benchmark at control period ``control_dt`` (s):
    the id's duration ``max_episode_steps * default_dt()`` divided by ``control_dt``, rounded
    down (at least one step)."""
    steps = int(benchmark_values(env_id)["max_episode_steps"])
    duration = steps * default_dt()
    return max(1, math.floor(duration / float(control_dt) + 1e-9))


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b or (isinstance(a, bool) and isinstance(b, bool) and a == b)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=0.0)
    return bool(a == b) if type(a) is type(b) else False


def evaluation_kwargs(env_id: str, model_kwargs: dict[str, Any],
                      overrides: dict[str, Any] | None = None, source: str = "config.yml"
                      ) -> tuple[dict[str, Any], dict[str, Any]]:
    """``gym.make`` keywords to evaluate a model of ``env_id`` with, and the task keywords the
    user overrode.

    The model's :data:`AGENT_KEYS` are kept, its :data:`REWARD_KEYS` dropped; a
    :data:`VIEWER_KEYS` entry, an unknown key, or a task key whose value differs from the id's
    (:func:`benchmark_values`; ``max_episode_steps``: from :func:`benchmark_steps`) raises
    :class:`UserError` naming the keys, unless ``overrides`` (the command line's task
    keywords) names them. ``overrides`` must name task keys only; its values are applied (and
    checked by the env). Returns ``(kwargs, applied overrides)``: empty overrides mean the
    benchmark's task.
    """
    overrides = dict(overrides or {})
    tasks = set(task_keys())
    bad = sorted(k for k in overrides if k not in tasks)
    if bad:
        raise UserError(f"task overrides: {short_repr(bad)} are not task keywords (task "
                        f"keywords: {', '.join(sorted(tasks))})")
    known = set(_all_keywords())
    unknown = sorted(str(k) for k in model_kwargs if k not in known)
    if unknown:
        raise UserError(f"{source}: unknown env keyword(s) {short_repr(unknown)}")
    viewer = sorted(k for k in model_kwargs if k in VIEWER_KEYS)
    if viewer:
        raise UserError(f"{source}: env keyword(s) {', '.join(viewer)} are not a model's to "
                        "set (rendering is the evaluation's choice)")
    kwargs = {k: v for k, v in model_kwargs.items() if k in AGENT_KEYS}
    bench = benchmark_values(env_id)
    dt = kwargs.get("control_dt", default_dt())
    if not (isinstance(dt, (int, float)) and not isinstance(dt, bool) and 0 < dt <= 1):
        raise UserError(f"{source}: control_dt must be a number in (0, 1] s (got "
                        f"{short_repr(dt)})")
    bench["max_episode_steps"] = benchmark_steps(env_id, float(dt))
    differ = sorted(k for k in model_kwargs if k in tasks and k not in overrides
                    and not _same(model_kwargs[k], bench[k]))
    if differ:
        shown = ", ".join(f"{k}={short_repr(model_kwargs[k])} (benchmark "
                          f"{short_repr(bench[k])})" for k in differ)
        raise UserError(f"{source} sets task keyword(s) the benchmark defines: {shown}; the "
                        f"registered id {env_id} defines the task (override them on the "
                        "command line to evaluate another task, labelled not the benchmark)")
    steps = overrides.get("max_episode_steps", bench["max_episode_steps"])
    if isinstance(steps, bool) or not isinstance(steps, int) or not (
            1 <= steps <= MAX_EPISODE_STEPS):
        raise UserError(f"max_episode_steps must be an int in [1, {MAX_EPISODE_STEPS}] (got "
                        f"{short_repr(steps)})")
    kwargs["max_episode_steps"] = steps
    kwargs.update({k: v for k, v in overrides.items() if k != "max_episode_steps"})
    return kwargs, overrides
