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
``SoftHand*-v1``            as above     each of the seven with :data:`V1_KWARGS` (the
                                         ``Random`` ones also :data:`V1_RANDOM_KWARGS`)
==========================  ===========  ==================================================

The ``-v0`` ids keep their original semantics (ideal sensing); ``-v1`` is the benchmark's
current version (see the Version History of :class:`SoftHandEnv`); :func:`registered_kwargs`
gives the keywords of any id.

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

#: The original ids -> task name.
V0_IDS: dict[str, str] = {
    "SoftHand-v0": "none",
    "SoftHandReorient-v0": "reorient",
    "SoftHandTranslate-v0": "translate",
    "SoftHandPose-v0": "pose",
    "SoftHandReorientRandom-v0": "reorient",
    "SoftHandTranslateRandom-v0": "translate",
    "SoftHandPoseRandom-v0": "pose",
}

#: The ``-v1`` ids -> task name, one per ``-v0`` id.
V1_IDS: dict[str, str] = {i.removesuffix("-v0") + "-v1": t for i, t in V0_IDS.items()}

#: Registered id -> task name (every version, the ``-v0`` ids first).
ENV_IDS: dict[str, str] = {**V0_IDS, **V1_IDS}

#: The ids of the randomisation ladder's top rung (:data:`RANDOM_KWARGS`), every version.
RANDOM_IDS = tuple(i for i in ENV_IDS if i[:-3].endswith("Random"))

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

#: Keywords of every ``-v1`` id, on top of the ``-v0`` id's: the one place that says what v1
#: changes (each stays overridable in ``gym.make``): the hard limits tested on every substep,
#: slip and tension judged on 20 ms windows of physical time (docs/slip_window.md), the
#: realistic sensor model (:mod:`softhand_env.envs.sensors`).
V1_KWARGS: dict[str, Any] = {
    "substep_limits": True,
    "slip_window_ms": 20.0,
    "sensor_model": "realistic",
}

#: Hand parameters of every ``-v1`` id (merged into the id's ``hand_overrides``): the ROS2
#: integrator at its default schedule (1 ms steps after each call's start, then up to 2 ms),
#: equal to RK4 at 0.1 ms within 0.04 mm / 0.08 deg on the paper's motions
#: (docs/integrator.md). A ``hand_overrides`` given to ``gym.make`` replaces the
#: registered one as a whole, so pass ``integrator`` with it to keep ROS2.
V1_HAND_OVERRIDES: dict[str, Any] = {
    "integrator": "ros2",
}

#: Keywords of the ``Random`` ``-v1`` ids on top of :data:`RANDOM_KWARGS` and
#: :data:`V1_KWARGS`: the torque sensors' gains drawn per episode.
V1_RANDOM_KWARGS: dict[str, Any] = {
    "rand_sensors": True,
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


def registered_kwargs(env_id: str) -> dict[str, Any]:
    """The keywords registered for ``env_id`` (a key of :data:`ENV_IDS`): the task, then
    :data:`RANDOM_KWARGS` (``Random`` ids), :data:`V1_KWARGS`, :data:`V1_HAND_OVERRIDES` (merged
    into ``hand_overrides``) and :data:`V1_RANDOM_KWARGS` (``Random`` ``-v1`` ids)."""
    if env_id not in ENV_IDS:
        raise ValueError(f"unknown soft-hand id {env_id!r}; ids: {', '.join(ENV_IDS)}")
    kwargs: dict[str, Any] = {"task": ENV_IDS[env_id]}
    random = env_id in RANDOM_IDS
    if random:
        kwargs.update(RANDOM_KWARGS)
    if env_id in V1_IDS:
        kwargs.update(V1_KWARGS)
        kwargs["hand_overrides"] = {**kwargs.get("hand_overrides", {}), **V1_HAND_OVERRIDES}
        if random:
            kwargs.update(V1_RANDOM_KWARGS)
    return kwargs


def register_envs() -> None:
    """Register every id of :data:`ENV_IDS` with Gymnasium (idempotent).

    Gymnasium warns on ``gym.make`` of an id whose newer version is registered; the ``-v0``
    ids are kept on purpose (original semantics, the shipped models), so that warning is
    filtered for them (a ``DeprecationWarning`` filter on its message).
    """
    import warnings

    import gymnasium as gym

    warnings.filterwarnings("ignore", message=r".*The environment SoftHand\w*-v0 is out of date",
                            category=DeprecationWarning)

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
            kwargs=registered_kwargs(env_id),
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
    "V0_IDS",
    "V1_IDS",
    "V1_KWARGS",
    "V1_RANDOM_KWARGS",
    "SoftHandEnv",
    "SoftHandVectorEnv",
    "register_envs",
    "registered_kwargs",
    "reward_threshold",
]
