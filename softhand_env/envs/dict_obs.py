"""Dict-observation variants: a goal-conditioned (HER-ready) one and a privileged one.

``gym.make(id, goal_obs=True)`` (goal tasks) returns the env under :class:`GoalObservation`::

    observation    float32 (blind_size,)    the blind frames of today's observation (joints,
                                            set-points, PID torques [, tactile]) and the
                                            grasp-onset entries (``onset_obs``); the goal
                                            entries move to desired_goal
    desired_goal   float64 (goal_dim,)      the goal, scaled as today's goal entries
                                            (x / 30 mm, theta / 30 deg)
    achieved_goal  float64 (goal_dim,)      the object's controlled coordinates, same units

and ``env.compute_reward(achieved_goal, desired_goal, info)`` (vectorised over leading axes;
``info`` one dict, a sequence of dicts or a dict of arrays) equals the step reward: the goal
and success terms are recomputed from the goals (success also needs ``info["grasped"]``), the
control and failure terms are taken from ``info`` (they do not depend on the goal). SB3's
``HerReplayBuffer`` keeps the infos only with ``replay_buffer_kwargs={"copy_info_dict":
True}``; without them ``compute_reward`` raises a ValueError saying so. The goal
is kept out of ``observation`` so that relabelling ``desired_goal`` (hindsight experience
replay) leaves no stale copy of the old goal for the policy to read. ``achieved_goal`` is
the object's pose: a blind policy must not read it (it is there for relabelling only; see
:mod:`agents.sb3.policies`).

``gym.make(id, privileged_obs=True)`` returns the env under :class:`PrivilegedObservation`::

    observation    float32 (size,)    exactly today's blind observation
    privileged     float32 (16 + goal_dim,) see PRIVILEGED_NAMES: object pose (x, y, theta)
                                      and velocity, deformations (d_n1, d_n2, d_t1, d_t2),
                                      the randomised parameters as relative deviations from
                                      the nominal hand (0 without randomisation), goal error
                                      (achieved - desired); scaled to O(1): positions / 30 mm,
                                      angles / 30 deg, velocities / 0.1 m/s and / 5 rad/s,
                                      d_n / 10 mm, d_t / 1 mm, deviations / 0.5

for an asymmetric actor-critic (the critic reads ``privileged``, the actor does not). Both
keywords together give the three keys of ``goal_obs`` plus ``privileged``.

The same keywords work with the native vector env (``gym.make_vec(id, num_envs=N,
vectorization_mode="vector_entry_point", goal_obs=True)``): :class:`VectorDictObservation`
builds the batched Dict observations (autoreset mode NextStep or Disabled). The wrappers
read the physics through :func:`physics_readouts` (the single env's public ``physics`` and
``goal``; the vector env's batched state).

The registered entry points are :func:`make_env` and :func:`make_vector_env`: they build
:class:`~softhand_env.envs.SoftHandEnv` / :class:`~softhand_env.envs.SoftHandVectorEnv` from
the other keywords and wrap them only when a keyword asks for it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorWrapper
from gymnasium.vector.utils import batch_space

from softhand_env.envs.observation import (
    ANGLE_SCALE,
    DN_SCALE,
    DT_SCALE,
    OBS_BOUND,
    POSITION_SCALE,
    VELOCITY_SCALE,
)
from softhand_env.envs.randomization import FIELDS
from softhand_env.envs.softhand import SoftHandEnv

#: Object linear velocities (m/s) in ``privileged`` are divided by this.
LINEAR_VELOCITY_SCALE = 0.1
#: Relative parameter deviations in ``privileged`` are divided by this (+-50 % -> +-1).
PARAM_DEVIATION_SCALE = 0.5
#: Names of the privileged entries before the goal error (one per ``rand_*`` keyword after
#: the physics read-outs).
PRIVILEGED_NAMES = (
    "x_obj", "y_obj", "theta_obj", "vx_obj", "vy_obj", "omega_obj",
    "d_n1", "d_n2", "d_t1", "d_t2",
    *(f"dev_{key[len('rand_'):]}" for key in FIELDS),
)
_PRIV_SCALES = np.array(
    [POSITION_SCALE, POSITION_SCALE, ANGLE_SCALE,
     LINEAR_VELOCITY_SCALE, LINEAR_VELOCITY_SCALE, VELOCITY_SCALE,
     DN_SCALE, DN_SCALE, DT_SCALE, DT_SCALE]
    + [PARAM_DEVIATION_SCALE] * len(FIELDS)
)
#: One representative field per ``rand_*`` keyword (the fields of one keyword share a factor).
_PARAM_FIELDS = tuple(fields[0] for fields in FIELDS.values())


class DictReadout:
    """Dict-observation pieces of one env configuration, for one env or a batch.

    Every method works on arrays with any leading (batch) axes.

    Parameters
    ----------
    config : EnvConfig
        The env's configuration (``env.unwrapped.config``).
    goal_obs, privileged_obs : bool
        Which keys to build (see module doc).
    """

    def __init__(self, config: Any, goal_obs: bool, privileged_obs: bool):
        _check_flags(goal_obs, privileged_obs)
        self.task = config.task
        if goal_obs and not self.task.goal_dim:
            raise ValueError(f"goal_obs=True needs a goal task (task {self.task.name!r} has none)")
        self.layout = config.layout
        self.nominal = config.params
        self.goal_obs = bool(goal_obs)
        self.privileged_obs = bool(privileged_obs)
        targets = self.task.targets
        self._obs_scales = np.array([t.obs_scale for t in targets])
        self._pose_index = np.array([t.index for t in targets], dtype=np.intp)
        self._nominal = np.array([getattr(config.params, f) for f in _PARAM_FIELDS])

    def space(self) -> spaces.Dict:
        """The single-env Dict observation space."""
        out: dict[str, spaces.Space] = {}
        bound = OBS_BOUND
        if self.goal_obs:
            g = self.task.goal_dim
            out["observation"] = spaces.Box(-bound, bound, (self.layout.blind_size,),
                                            np.float32)
            out["desired_goal"] = spaces.Box(-bound, bound, (g,), np.float64)
            out["achieved_goal"] = spaces.Box(-bound, bound, (g,), np.float64)
        else:
            out["observation"] = self.layout.space()
        if self.privileged_obs:
            size = len(PRIVILEGED_NAMES) + self.task.goal_dim
            out["privileged"] = spaces.Box(-bound, bound, (size,), np.float32)
        return spaces.Dict(out)

    def goal_units(self, goal_si: np.ndarray) -> np.ndarray:
        """Goal(s) (SI, (..., goal_dim)) in the scaled units of the observation."""
        return np.clip(np.asarray(goal_si, dtype=np.float64) / self._obs_scales,
                       -OBS_BOUND, OBS_BOUND)

    def achieved(self, object_pose: np.ndarray) -> np.ndarray:
        """Achieved goal(s) from ``info["object_pose"]`` (..., 3) (m, m, rad), scaled."""
        return self.goal_units(np.asarray(object_pose)[..., self._pose_index])

    def privileged(
        self,
        object_pose: np.ndarray,
        object_velocity: np.ndarray,
        deformation: np.ndarray,
        param_values: np.ndarray,
        goal_si: np.ndarray,
    ) -> np.ndarray:
        """The privileged vector(s), float32 (..., 16 + goal_dim).

        Parameters
        ----------
        object_pose : (..., 3)  x, y (m), theta (rad)
        object_velocity : (..., 3)  m/s, m/s, rad/s
        deformation : (..., 4)  d_n1, d_n2, d_t1, d_t2 (m)
        param_values : (..., 6)  the drawn values of the ``rand_*`` fields (SI)
        goal_si : (..., goal_dim)  goal (SI)
        """
        dev = np.asarray(param_values) / self._nominal - 1.0
        raw = np.concatenate([object_pose, object_velocity, deformation, dev], axis=-1)
        err = np.asarray(object_pose)[..., self._pose_index] - np.asarray(goal_si)
        out = np.concatenate([raw / _PRIV_SCALES, err / self._obs_scales], axis=-1)
        return np.clip(out, -OBS_BOUND, OBS_BOUND).astype(np.float32)

    def param_values(self, params: Any) -> np.ndarray:
        """The ``rand_*`` fields of a HandParams, shape (6,)."""
        return np.array([getattr(params, f) for f in _PARAM_FIELDS])

    def build(self, obs: np.ndarray, physics: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Dict observation(s) from the Box observation(s) and the physics read-outs.

        ``physics``: ``object_pose`` (..., 3), ``object_velocity`` (..., 3), ``deformation``
        (..., 4), ``params`` (..., 6) (see :meth:`privileged`) and ``goal`` (..., goal_dim).
        """
        out: dict[str, np.ndarray] = {}
        goal = physics["goal"]
        if self.goal_obs:
            out["observation"] = np.asarray(obs)[..., : self.layout.blind_size].copy()
            out["desired_goal"] = self.goal_units(goal)
            out["achieved_goal"] = self.achieved(physics["object_pose"])
        else:
            out["observation"] = np.asarray(obs).copy()
        if self.privileged_obs:
            out["privileged"] = self.privileged(
                physics["object_pose"], physics["object_velocity"], physics["deformation"],
                physics["params"], goal)
        return out

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The step reward for (relabelled) goals; arrays (..., goal_dim) -> (...,).

        ``info``: the step's info dict, a sequence/array of them (one per row), or a dict of
        arrays. Needs ``grasped``, ``reward_ctrl`` and ``reward_failure``.
        """
        a = np.asarray(achieved_goal, dtype=np.float64) * self._obs_scales
        d = np.asarray(desired_goal, dtype=np.float64) * self._obs_scales
        grasped = _info_field(info, "grasped")
        yt = {t.index: a[..., k] for k, t in enumerate(self.task.targets)}
        goal = tuple(d[..., k] for k in range(self.task.goal_dim))
        (r_goal, r_success, _, _), _ = self.task.evaluate(yt, goal, 0.0, False, grasped)
        reward = 0.0 + r_goal + r_success + _info_field(info, "reward_ctrl")
        reward = reward + _info_field(info, "reward_failure")
        return reward.item() if np.ndim(reward) == 0 else reward


def _check_flags(goal_obs: Any, privileged_obs: Any) -> None:
    for name, value in (("goal_obs", goal_obs), ("privileged_obs", privileged_obs)):
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"{name} must be True or False (got {value!r})")


def _info_field(info: Any, key: str) -> np.ndarray:
    """``info[key]`` of one info dict or a dict of arrays, or stacked over a sequence of dicts."""
    try:
        if isinstance(info, Mapping):
            return np.asarray(info[key])
        if isinstance(info, np.ndarray) or isinstance(info, Sequence):
            arr = np.asarray(info, dtype=object)
            return np.array([i[key] for i in arr.ravel()]).reshape(arr.shape)
    except KeyError:
        raise ValueError(
            f"compute_reward needs info[{key!r}] (the step's info: grasped, reward_ctrl, "
            "reward_failure); with SB3's HerReplayBuffer pass "
            "replay_buffer_kwargs={'copy_info_dict': True}"
        ) from None
    raise TypeError(f"info must be a dict or a sequence of dicts (got {type(info).__name__})")


def physics_readouts(env: Any, readout: DictReadout,
                     values: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Object pose and velocity, deformations, drawn parameters and goal of an unwrapped env.

    Single env (its one-hand ``physics`` and ``goal``): shapes (3,), (3,), (4,), (6,),
    (goal_dim,). Native vector env (its N-hand ``physics``, all N rows whatever was reset):
    (N, 3), (N, 3), (N, 4), (N, 6), (N, goal_dim). Units as :meth:`DictReadout.privileged`.
    ``values``: the drawn parameters if the caller has them (else read from the physics).
    """
    physics = env.physics
    params = physics.params
    if isinstance(params, tuple):  # the vector env's batched physics: one HandParams per env
        if values is None:
            values = np.array([readout.param_values(p) for p in params])
        goal = env.goals
    else:
        if values is None:
            values = readout.param_values(params)
        goal = env.goal
    return {
        "object_pose": physics.object_pose,
        "object_velocity": physics.object_velocity,
        "deformation": physics.deformation,
        "params": values,
        "goal": goal,
    }


class _DictObservation(gym.Wrapper):
    """Single env with a Dict observation (see module doc)."""

    def __init__(self, env: gym.Env, goal_obs: bool, privileged_obs: bool):
        super().__init__(env)
        base: Any = env.unwrapped
        self.readout = DictReadout(base.config, goal_obs, privileged_obs)
        self.observation_space = self.readout.space()

    def _build(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        return self.readout.build(obs, physics_readouts(self.env.unwrapped, self.readout))

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self._build(obs), info

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._build(obs), reward, terminated, truncated, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """See :meth:`DictReadout.compute_reward`."""
        return self.readout.compute_reward(achieved_goal, desired_goal, info)


class GoalObservation(_DictObservation):
    """``goal_obs=True``: observation / desired_goal / achieved_goal (see module doc)."""

    def __init__(self, env: gym.Env, privileged_obs: bool = False):
        super().__init__(env, True, privileged_obs)


class PrivilegedObservation(_DictObservation):
    """``privileged_obs=True``: observation / privileged (see module doc)."""

    def __init__(self, env: gym.Env):
        super().__init__(env, False, True)


class VectorDictObservation(VectorWrapper):
    """The Dict observations of :class:`GoalObservation` / :class:`PrivilegedObservation`
    for the native vector env, batched (autoreset NextStep or Disabled)."""

    def __init__(self, env: gym.vector.VectorEnv, goal_obs: bool, privileged_obs: bool):
        super().__init__(env)
        if AutoresetMode(env.metadata.get("autoreset_mode")) == AutoresetMode.SAME_STEP:
            raise ValueError("Dict observations on the vector env need autoreset NextStep or "
                             "Disabled (SameStep's final_obs is not converted)")
        base: Any = env.unwrapped
        self.readout = DictReadout(base.config, goal_obs, privileged_obs)
        self.single_observation_space = self.readout.space()
        self.observation_space = batch_space(self.single_observation_space, env.num_envs)
        # the drawn parameters of each hand, read again only when its HandParams (immutable)
        # is another object: episodes restart a few hands a step
        self._params: list[Any] = [None] * env.num_envs
        self._values = np.zeros((env.num_envs, len(_PARAM_FIELDS)))

    def _param_values(self) -> np.ndarray:
        """The drawn parameters of every hand, (N, 6) (fresh)."""
        base: Any = self.env.unwrapped
        for i, params in enumerate(base.physics.params):
            if params is not self._params[i]:
                self._params[i] = params
                self._values[i] = self.readout.param_values(params)
        return self._values.copy()

    def _build(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        return self.readout.build(obs, physics_readouts(self.env.unwrapped, self.readout,
                                                        self._param_values()))

    def reset(self, *, seed: Any = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self._build(obs), info

    def step(self, actions: Any):
        obs, reward, terminated, truncated, info = self.env.step(actions)
        return self._build(obs), reward, terminated, truncated, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """See :meth:`DictReadout.compute_reward`."""
        return self.readout.compute_reward(achieved_goal, desired_goal, info)


def _wrap_single(env: gym.Env, goal_obs: bool, privileged_obs: bool) -> gym.Env:
    _check_flags(goal_obs, privileged_obs)
    if goal_obs:
        return GoalObservation(env, privileged_obs=privileged_obs)
    if privileged_obs:
        return PrivilegedObservation(env)
    return env


def make_env(goal_obs: bool = False, privileged_obs: bool = False, **kwargs: Any) -> gym.Env:
    """Registered entry point: :class:`SoftHandEnv` (``**kwargs``), Dict-wrapped on request.

    Parameters
    ----------
    goal_obs : bool
        :class:`GoalObservation` (goal tasks only).
    privileged_obs : bool
        Add the ``privileged`` key (:class:`PrivilegedObservation`).
    **kwargs
        Keywords of :class:`~softhand_env.envs.SoftHandEnv`.
    """
    return _wrap_single(SoftHandEnv(**kwargs), goal_obs, privileged_obs)


def make_vector_env(
    num_envs: int = 1, goal_obs: bool = False, privileged_obs: bool = False, **kwargs: Any
) -> gym.vector.VectorEnv:
    """Registered vector entry point: :class:`SoftHandVectorEnv`, Dict-wrapped on request."""
    from softhand_env.envs.vector import SoftHandVectorEnv

    _check_flags(goal_obs, privileged_obs)
    env = SoftHandVectorEnv(num_envs=num_envs, **kwargs)
    if goal_obs or privileged_obs:
        return VectorDictObservation(env, goal_obs, privileged_obs)
    return env

