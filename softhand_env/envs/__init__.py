"""Gymnasium environments of the soft hand (physics / task / environment, dm_control style).

Importing :mod:`softhand_env` calls :func:`register_envs`, which registers

==========================  ===========  ==================================================
id                          task         goal
==========================  ===========  ==================================================
``SoftHand-v0``             ``none``     none, reward 0 (scripted replay and evaluation)
``SoftHandReorient-v0``     ``reorient`` object angle theta_obj to a sampled target
``SoftHandTranslate-v0``    ``translate`` object position x_obj to a sampled target
``SoftHandPose-v0``         ``pose``     x_obj and theta_obj together
``SoftHand*Random-v0``      as above     Reorient, Translate, Pose with :data:`RANDOM_KWARGS`
==========================  ===========  ==================================================

all with the entry point :class:`SoftHandEnv` (the task is a keyword), ``max_episode_steps``
from ``configs/tasks/<task>.yaml``, ``reward_threshold`` (:func:`reward_threshold`) and the
vector entry point :class:`SoftHandVectorEnv`
(``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``), both built by
the factories of :mod:`.dict_obs`, which add Dict observations on ``goal_obs=True`` /
``privileged_obs=True`` and otherwise return the env itself. Registration imports only
Gymnasium and PyYAML; the physics is imported when an environment is made.

Modules: :mod:`.softhand` (the env and its manual), :mod:`.vector` (batched env),
:mod:`.transition` (the control step both run), :mod:`.tasks`, :mod:`.task_configs`,
:mod:`.actions`, :mod:`.observation`, :mod:`.randomization`, :mod:`.start` (grasp phase),
:mod:`.config`, :mod:`.rendering`, :mod:`.dict_obs` (goal-conditioned and privileged Dict
observations).
"""

from __future__ import annotations

from typing import Any

#: Registered id -> task name.
ENV_IDS: dict[str, str] = {
    "SoftHand-v0": "none",
    "SoftHandReorient-v0": "reorient",
    "SoftHandTranslate-v0": "translate",
    "SoftHandPose-v0": "pose",
    "SoftHandReorientRandom-v0": "reorient",
    "SoftHandTranslateRandom-v0": "translate",
    "SoftHandPoseRandom-v0": "pose",
}

#: The ids of the randomisation ladder's top rung (:data:`RANDOM_KWARGS`).
RANDOM_IDS = tuple(i for i in ENV_IDS if i.endswith("Random-v0"))

#: Keywords of the ``Random`` ids (the randomisation ladder's top rung), on top of the task:
#: relative half-widths of the hand parameters (friction included), observation noise, a
#: set-point latency of 0 or 1 control steps per episode, and the RK4 substep halved (0.05 ms),
#: at which every corner of these ranges is within RK4's stability region (at 0.1 ms the
#: lightest, softest, least damped corner is not). Post-grasp d_n stays below a/2
#: (tests/envs/test_random.py).
RANDOM_KWARGS: dict[str, Any] = {
    "rand_width": 0.1,
    "rand_mass": 0.5,
    "rand_inertia": 0.5,
    "rand_stiffness": 0.3,
    "rand_damping": 0.3,
    "rand_gains": 0.3,
    "rand_friction": 0.2,  # mu = 1.0 +- 20 %: above the 0.66 the shipped agents need
    "obs_noise": 0.01,
    "setpoint_latency": 1,
    "hand_overrides": {"dt": 5e-5},
}

ENTRY_POINT = "softhand_env.envs.dict_obs:make_env"
VECTOR_ENTRY_POINT = "softhand_env.envs.dict_obs:make_vector_env"


def reward_threshold(task_config: dict[str, Any]) -> float | None:
    """Episode return at which a goal task counts as solved: ``max_episode_steps *
    goal_weight`` (None for the task ``none``, which has no reward).

    Per step, ``reward_goal`` stays below ``goal_weight`` (it equals it only with zero error),
    so an average of ``goal_weight`` per step is reached only by episodes that spend a good part
    of their time within the success tolerance (where ``reward_success`` is added), e.g. about
    a third of the steps if the rest average half the goal reward.
    """
    if "goal_weight" not in task_config:
        return None
    return float(task_config["max_episode_steps"]) * float(task_config["goal_weight"])


def register_envs() -> None:
    """Register every id of :data:`ENV_IDS` with Gymnasium (idempotent)."""
    import gymnasium as gym

    from softhand_env.envs.task_configs import load_task_config

    for env_id, task in ENV_IDS.items():
        if env_id in gym.registry:
            continue
        config = load_task_config(task)
        gym.register(
            id=env_id,
            entry_point=ENTRY_POINT,
            vector_entry_point=VECTOR_ENTRY_POINT,
            max_episode_steps=int(config["max_episode_steps"]),
            reward_threshold=reward_threshold(config),
            kwargs={"task": task, **(RANDOM_KWARGS if env_id in RANDOM_IDS else {})},
        )


def __getattr__(name: str) -> Any:
    if name == "SoftHandEnv":
        from softhand_env.envs.softhand import SoftHandEnv

        return SoftHandEnv
    if name == "SoftHandVectorEnv":
        from softhand_env.envs.vector import SoftHandVectorEnv

        return SoftHandVectorEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ENV_IDS",
    "RANDOM_IDS",
    "RANDOM_KWARGS",
    "SoftHandEnv",
    "SoftHandVectorEnv",
    "register_envs",
    "reward_threshold",
]
