"""Native vector environment: N soft hands in one :class:`~.transition.EpisodeBatch`.

:class:`SoftHandVectorEnv` is a :class:`gymnasium.vector.VectorEnv` with the same keywords,
spaces, rewards, info keys and per-environment seeding as N copies of
:class:`~softhand_env.envs.SoftHandEnv` under :class:`gymnasium.vector.SyncVectorEnv`: with
``reset(seed=s)`` environment i is seeded with ``s + i``, keeps its own ``np_random`` (goals,
randomisation, noise), its own time-limit counter, and autoresets per
``metadata["autoreset_mode"]`` (``NextStep`` by default, ``SameStep``, or ``Disabled`` with
``reset(options={"reset_mask": mask})``). Results agree with the single environments to
bit for bit: both run the same transition (:mod:`softhand_env.envs.transition`); the physics runs
in parallel over numba threads.

Create it with ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from softhand_env.envs.actions import action_array
from softhand_env.envs.config import build_config
from softhand_env.envs.options import (
    MAX_EPISODE_STEPS,
    MAX_NUM_ENVS,
    EnvOptions,
    arguments_table,
    check_count,
    check_seed,
    keyword_signature,
)
from softhand_env.envs.task_configs import load_task_config
from softhand_env.envs.transition import EpisodeBatch, reset_goal

if TYPE_CHECKING:
    from softhand_env.envs.rendering import SceneRenderer


class SoftHandVectorEnv(VectorEnv):
    """N independent soft hands in one batch (see module doc).

    Parameters
    ----------
    num_envs : int
        Number of environments N, an int in [1, 65536] (``MAX_NUM_ENVS``).
    max_episode_steps : int, optional
        Per-environment time limit in control steps (truncation), an int in [1, 1e7]
        (``MAX_EPISODE_STEPS``); ``None`` uses the task's ``configs/tasks/<task>.yaml`` value
        (``make_vec`` passes the registered one).
    autoreset_mode : AutoresetMode or str
        ``"NextStep"`` (default), ``"SameStep"`` or ``"Disabled"``.
    **kwargs
        Keywords of :class:`~softhand_env.envs.SoftHandEnv`, collected in an
        :class:`~softhand_env.envs.options.EnvOptions` (``render_mode`` may be None or
        ``"rgb_array"``: :meth:`render` returns one frame per environment); the signature
        of ``__init__`` lists them (``inspect.signature``, ``help``), and this table
        (:func:`~softhand_env.envs.options.arguments_table`):

{ARGUMENTS_TABLE}
    """

    metadata = {
        "render_modes": ["rgb_array"],
        "render_fps": 50,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs: Any,
    ):
        options = EnvOptions(**kwargs)
        if options.render_mode == "human":
            raise ValueError("SoftHandVectorEnv supports render_mode None or 'rgb_array'")
        cfg = build_config(options)
        #: The keywords of these environments (:class:`~softhand_env.envs.options.EnvOptions`).
        self.options = options
        n = check_count("num_envs", num_envs, MAX_NUM_ENVS)
        if max_episode_steps is None:
            max_episode_steps = load_task_config(options.task)["max_episode_steps"]
        max_episode_steps = check_count("max_episode_steps", max_episode_steps,
                                        MAX_EPISODE_STEPS)
        self.config = cfg
        self.task = cfg.task
        self.num_envs = n
        self.max_episode_steps = int(max_episode_steps)
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.render_mode = options.render_mode
        self.dt = cfg.dt
        self.metadata = {
            **type(self).metadata,
            "render_fps": 1.0 / cfg.dt,
            "autoreset_mode": self.autoreset_mode,
        }
        self.single_action_space = cfg.actions.space()
        self.single_observation_space = cfg.layout.space()
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self._batch = EpisodeBatch(cfg, n)
        #: The N hands (:class:`~softhand_env.physics.HandPhysics`, read-outs (N, ...)).
        self.physics = self._batch.physics
        self._steps = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=bool)
        self._was_reset = np.zeros(n, dtype=bool)
        self._all_reset = False  # every environment reset once (then _was_reset stays True)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._seeds: list[int | None] = [None] * n
        self._renderer: SceneRenderer | None = None
        #: ``"_" + key`` of each info key, the key of its mask
        self._mask_keys = {key: f"_{key}" for key in self._batch.info_values()}

    # ------------------------------------------------------------------------------ reset
    @property
    def np_random_seed(self) -> tuple[int | None, ...]:  # type: ignore[override]  # per env
        """Seeds of the environments' generators (as :class:`SyncVectorEnv` reports them)."""
        return tuple(self._seeds)

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset all environments, or those of ``options["reset_mask"]`` (bool (N,)).

        ``seed``: None (keep each generator; seed fresh ones from entropy), an int s >= 0
        (env i gets s + i) or a list of N ints/None (the single env's rule,
        :func:`~softhand_env.envs.options.check_seed`). ``options["goal"]``: a goal
        (goal_dim,) (SI) for every environment reset, or (N, goal_dim) one per environment.
        Other option keys raise
        ``ValueError``; ``step`` before every environment was reset raises ``ResetNeeded``.
        """
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (list, tuple, np.ndarray)):
            seeds = [check_seed(s, f"seed[{i}]") for i, s in enumerate(seed)]
            if len(seeds) != n:
                raise ValueError(f"seed list must have length num_envs={n} (got {len(seeds)})")
        else:
            first = check_seed(seed)
            assert first is not None
            seeds = [first + i for i in range(n)]
        goal = reset_goal(options, ("goal", "reset_mask"))
        mask = np.ones(n, dtype=bool)
        if options is not None and "reset_mask" in options:
            mask = options["reset_mask"]
            if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,)):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},)")
        goals = self._goal_rows(goal)
        rows = np.flatnonzero(mask)
        for i in rows:
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i], self._seeds[i] = seeding.np_random(seeds[i])
        self._reset_rows(mask, None if goals is None else [goals[i] for i in rows])
        self._was_reset[mask] = True
        self._autoreset[mask] = False
        return self._batch.obs.copy(), self._infos(mask)

    def _goal_rows(self, goal: Any) -> Any:
        """``reset(options={"goal": g})``: g (goal_dim,) for every environment, or (N,
        goal_dim) one row per environment; None without a goal option."""
        if goal is None:
            return None
        if np.ndim(goal) == 2:
            g = np.asarray(goal)
            if g.shape[0] != self.num_envs:
                raise ValueError(
                    f"options['goal'] must have shape (goal_dim,) or ({self.num_envs}, "
                    f"goal_dim) (got {g.shape})"
                )
            return list(g)
        return [goal] * self.num_envs

    def _reset_rows(self, mask: np.ndarray, goals: list[Any] | None = None) -> None:
        """Start new episodes in the environments of ``mask`` (their own generators; one goal
        per environment of ``mask`` if given)."""
        rows = np.flatnonzero(mask)
        self._batch.start_rows(rows, [self._rngs[i] for i in rows], goals)
        self._batch.finish_reset(mask, self._rngs)
        self._steps[mask] = 0

    # ------------------------------------------------------------------------------- step
    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        n = self.num_envs
        if not self._all_reset:
            if not self._was_reset.all():
                raise ResetNeeded(
                    "Cannot call step() before reset() of every environment "
                    f"(never reset: {np.flatnonzero(~self._was_reset).tolist()})"
                )
            self._all_reset = True
        actions = action_array(actions, (n, 2))
        resetting = (
            self._autoreset.copy()
            if self.autoreset_mode == AutoresetMode.NEXT_STEP
            else np.zeros(n, dtype=bool)
        )
        restart = bool(resetting.any())
        if restart:
            actions = np.array(actions, dtype=np.float64)
            actions[resetting] = 0.0  # ignored: these environments restart (as in Sync)
        batch = self._batch
        rewards, terminated = batch.step(actions, self._rngs, skip=resetting)
        self._steps += 1
        truncated = self._steps >= self.max_episode_steps
        # NextStep: environments that ended on the previous step restart now
        if restart:
            self._reset_rows(resetting)
            rewards[resetting] = 0.0
            terminated[resetting] = False
            truncated[resetting] = False
        infos = self._infos()
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            infos = self._same_step_reset(done, infos)
        self._autoreset = done
        return batch.obs.copy(), rewards, terminated, truncated, infos

    def _same_step_reset(self, done: np.ndarray, step_infos: dict[str, Any]) -> dict[str, Any]:
        """Record final observations/infos of finished environments and reset them now."""
        n = self.num_envs
        final_obs = np.full(n, None, dtype=object)
        for i in np.flatnonzero(done):
            final_obs[i] = self._batch.obs[i].copy()
        final_info = {}
        for key, value in step_infos.items():
            if not key.startswith("_"):
                mask = step_infos[f"_{key}"] & done
                kept = np.full_like(value, None) if value.dtype == object else np.zeros_like(value)
                kept[mask] = value[mask]
                final_info[key], final_info[f"_{key}"] = kept, mask
        self._reset_rows(done)
        infos = self._infos()
        infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
        infos["final_info"], infos["_final_info"] = final_info, done.copy()
        return infos

    # ---------------------------------------------------------------------------- helpers
    def _infos(self, mask: np.ndarray | None = None) -> dict[str, Any]:
        """Batched info of the environments of ``mask`` (bool (N,); None: all), each key
        with its ``_key`` mask, as :class:`SyncVectorEnv` builds it."""
        values = self._batch.info_values()
        # one mask row per key, none shared
        if mask is None or mask.all():
            masks = np.ones((len(values), self.num_envs), dtype=bool)
        else:
            masks = np.empty((len(values), mask.size), dtype=bool)
            masks[:] = mask
            for key, value in values.items():
                kept = np.full_like(value, None) if value.dtype == object else np.zeros_like(value)
                kept[mask] = value[mask]
                values[key] = kept
        mask_keys = self._mask_keys
        infos: dict[str, Any] = {}
        for (key, value), key_mask in zip(values.items(), masks, strict=True):
            infos[key] = value
            infos[mask_keys[key]] = key_mask
        return infos

    @property
    def goals(self) -> np.ndarray:
        """Current goals (SI), shape (N, goal_dim)."""
        return self._batch.goal.copy()

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One RGB frame per environment (``render_mode="rgb_array"``), else None."""
        if self.render_mode is None:
            return None
        if self._renderer is None:
            from softhand_env.envs.rendering import SceneRenderer

            self._renderer = SceneRenderer(self.config.params, *self.config.render_size)
        p = self.physics
        pose, angles, deformation, setpoint = (
            p.object_pose, p.finger_angles, p.deformation, p.setpoint
        )
        frames = []
        for i in range(self.num_envs):
            goal_pose = self.task.goal_pose(pose[i], self._batch.goal[i])
            frames.append(self._renderer.frame(pose[i], angles[i], deformation[i], setpoint[i],
                                               p.params[i], goal_pose))
        return tuple(frames)

    def close_extras(self, **kwargs: Any) -> None:
        self._renderer = None


SoftHandVectorEnv.__doc__ = (SoftHandVectorEnv.__doc__ or "").replace(
    "{ARGUMENTS_TABLE}", arguments_table("markdown", indent=4)
)
# the keywords in the signature for help() and IDEs that read it at run time
SoftHandVectorEnv.__init__.__signature__ = keyword_signature(  # type: ignore[attr-defined]
    SoftHandVectorEnv.__init__
)
