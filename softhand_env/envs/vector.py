"""Native vector environment: N soft hands advanced together by :func:`kernel.advance_batch`.

:class:`SoftHandVectorEnv` is a :class:`gymnasium.vector.VectorEnv` with the same keywords,
spaces, rewards, info keys and per-environment seeding as N copies of
:class:`~softhand_env.envs.SoftHandEnv` under :class:`gymnasium.vector.SyncVectorEnv`: with
``reset(seed=s)`` environment i is seeded with ``s + i``, keeps its own ``np_random`` (goals,
randomisation, noise), its own time-limit counter, and autoresets per
``metadata["autoreset_mode"]`` (``NextStep`` by default, ``SameStep``, or ``Disabled`` with
``reset(options={"reset_mask": mask})``). Results agree with the single environments to
round-off; the physics runs in parallel over numba threads.

Create it with ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
"""

from __future__ import annotations

import inspect
import math
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from softhand_env import kernel
from softhand_env.envs.config import build_config
from softhand_env.envs.observation import add_frame_noise, observe_batch, reset_observation
from softhand_env.envs.softhand import SoftHandEnv
from softhand_env.envs.start import start_episode
from softhand_env.envs.task_configs import load_task_config
from softhand_env.envs.tasks import failure_state, step_flags, termination_reason
from softhand_env.model import DN_1, DT_2, NY, TH_OBJ, X_OBJ, pack_params
from softhand_env.physics import warn_if_unstable


class SoftHandVectorEnv(VectorEnv):
    """N independent soft hands in one batch (see module doc).

    Parameters
    ----------
    num_envs : int
        Number of environments N.
    max_episode_steps : int, optional
        Per-environment time limit in control steps (truncation); ``None`` uses the task's
        ``configs/tasks/<task>.yaml`` value (``make_vec`` passes the registered one).
    autoreset_mode : AutoresetMode or str
        ``"NextStep"`` (default), ``"SameStep"`` or ``"Disabled"``.
    **kwargs
        Keywords of :class:`~softhand_env.envs.SoftHandEnv` (``render_mode`` may be None or
        ``"rgb_array"``: :meth:`render` returns one frame per environment).
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
        bound = inspect.signature(SoftHandEnv.__init__).bind(None, **kwargs)
        bound.apply_defaults()
        args = dict(bound.arguments)
        del args["self"]
        if args["render_mode"] == "human":
            raise ValueError("SoftHandVectorEnv supports render_mode None or 'rgb_array'")
        cfg = build_config(**args)
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)):
            raise ValueError(f"num_envs must be an int >= 1 (got {num_envs!r})")
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1 (got {num_envs!r})")
        if max_episode_steps is None:
            max_episode_steps = load_task_config(args["task"])["max_episode_steps"]
        if int(max_episode_steps) < 1:
            raise ValueError(f"max_episode_steps must be >= 1 (got {max_episode_steps!r})")
        n = int(num_envs)
        self.config = cfg
        self.task = cfg.task
        self.num_envs = n
        self.max_episode_steps = int(max_episode_steps)
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.render_mode = args["render_mode"]
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
        warn_if_unstable(cfg.params)
        prm = pack_params(cfg.params)
        self._params = [cfg.params] * n
        self._PRM = np.ascontiguousarray(np.tile(prm, (n, 1)))
        self._Y = np.zeros((n, NY))
        self._U = np.tile(cfg.grasp_setpoint, (n, 1))
        self._goal = np.zeros((n, cfg.task.goal_dim))
        self._obs = np.zeros((n, cfg.layout.size), dtype=np.float32)
        self._diag = np.zeros((n, 2))
        self._flags = np.zeros(n, dtype=np.int64)
        self._ce = np.zeros((n, 2))
        self._grasped = np.zeros(n, dtype=bool)
        self._success = np.zeros(n, dtype=bool)
        self._terms = np.zeros((len(cfg.task.terms), n))
        self._steps = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=bool)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._seeds: list[int | None] = [None] * n
        self._renderer = None

    # ------------------------------------------------------------------------------ reset
    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        """Seeds of the environments' generators (as :class:`SyncVectorEnv` reports them)."""
        return tuple(self._seeds)

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset all environments, or those of ``options["reset_mask"]`` (bool (N,)).

        ``seed``: None (keep each generator; seed fresh ones from entropy), an int s (env i
        gets s + i) or a list of N ints/None.
        """
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed list must have length num_envs={n} (got {len(seeds)})")
        mask = np.ones(n, dtype=bool)
        if options is not None and "reset_mask" in options:
            mask = options["reset_mask"]
            if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,)):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},)")
        for i in np.flatnonzero(mask):
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i], self._seeds[i] = seeding.np_random(seeds[i])
            self._reset_one(i)
        self._autoreset[mask] = False
        return self._obs.copy(), self._infos(mask)

    def _reset_one(self, i: int) -> None:
        """Start a new episode in environment i (row i of every array)."""
        cfg, rng = self.config, self._rngs[i]
        start = start_episode(cfg, rng, self._params[i], self._PRM[i])
        if start.params is not self._params[i]:
            self._params[i] = start.params
            self._PRM[i] = start.prm
        self._Y[i] = start.state
        self._U[i] = start.setpoint
        self._goal[i] = start.goal
        reset_observation(
            self._obs[i],
            cfg.layout,
            self._Y[i],
            self._U[i],
            self._PRM[i],
            self.task.goal_observation(start.goal),
            cfg.randomization.obs_noise,
            rng,
        )
        self._ce[i] = start.constraint_error
        self._grasped[i] = start.grasped
        self._success[i] = start.success
        self._terms[:, i] = 0.0
        self._flags[i] = 0
        self._steps[i] = 0

    # ------------------------------------------------------------------------------- step
    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        cfg, n = self.config, self.num_envs
        layout = cfg.layout
        resetting = (
            self._autoreset.copy()
            if self.autoreset_mode == AutoresetMode.NEXT_STEP
            else np.zeros(n, dtype=bool)
        )
        if resetting.any() and np.shape(actions) == self._U.shape:
            actions = np.array(actions, dtype=np.float64)
            actions[resetting] = 0.0  # ignored: these environments restart (as in Sync)
        U_new, ctrl = cfg.actions.setpoints(actions, self._U)
        self._U[:] = U_new
        Y_prev = self._Y.copy()
        flags = self._flags
        flags[:] = 0
        flags[resetting] = kernel.FLAG_SKIP  # these environments restart instead
        kernel.advance_batch(
            self._Y, self._U, self._PRM, cfg.n_substeps, cfg.ch_limit, self._diag, flags
        )
        flags[:] = step_flags(flags, self._diag[:, 0], cfg.ch_limit)
        flags[resetting] = 0  # (their DIAG rows are stale: the kernel skipped them)
        ce = self._ce
        ce[:] = self._diag
        if (flags & kernel.FATAL_FLAGS).any():
            ce[~np.isfinite(ce)] = math.inf
            rollback = (flags & kernel.FLAG_NONFINITE) != 0
            self._Y[rollback] = Y_prev[rollback]  # last finite state: obs and info stay finite
        Yt = self._Y.T
        failed, grasped, _, _ = failure_state(
            flags, Yt, cfg.dn_limit, cfg.params.a, cfg.base_limit
        )
        goal_cols = tuple(self._goal.T)
        terms, success = self.task.evaluate(Yt, goal_cols, ctrl, failed, grasped)
        self._terms[:] = np.array(terms).reshape(len(self.task.terms), n)
        rewards = self._terms.sum(axis=0)
        self._grasped[:] = grasped
        self._success[:] = success
        terminated = failed | (success & self.task.terminate_on_success)
        self._steps += 1
        truncated = self._steps >= self.max_episode_steps
        # observations: shift the history, write the newest frames
        f, h = layout.frame_size, layout.history_size
        if h > f:
            self._obs[:, f:h] = self._obs[:, : h - f]
        observe_batch(self._Y, self._U, self._PRM, layout.tactile, self._obs)
        noise = cfg.randomization.obs_noise
        if noise > 0:
            for i in np.flatnonzero(~resetting):
                add_frame_noise(self._obs[i, :f], noise, self._rngs[i])
        reasons = None
        if terminated.any():
            reasons = np.full(n, None, dtype=object)
            for i in np.flatnonzero(terminated & ~resetting):
                reasons[i] = (
                    termination_reason(int(flags[i]), self._Y[i], cfg.dn_limit)
                    if failed[i]
                    else "success"
                )
        # NextStep: environments that ended on the previous step restart now
        for i in np.flatnonzero(resetting):
            self._reset_one(i)
        rewards[resetting] = 0.0
        terminated[resetting] = False
        truncated[resetting] = False
        if reasons is not None:
            reasons[resetting] = None
        infos = self._infos(np.ones(n, dtype=bool), reasons)
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            infos = self._same_step_reset(done, infos)
        self._autoreset = done
        return self._obs.copy(), rewards, terminated, truncated, infos

    def _same_step_reset(self, done: np.ndarray, step_infos: dict[str, Any]) -> dict[str, Any]:
        """Record final observations/infos of finished environments and reset them now."""
        n = self.num_envs
        final_obs = np.full(n, None, dtype=object)
        for i in np.flatnonzero(done):
            final_obs[i] = self._obs[i].copy()
        final_info = {}
        for key, value in step_infos.items():
            if not key.startswith("_"):
                mask = step_infos[f"_{key}"] & done
                kept = np.full_like(value, None) if value.dtype == object else np.zeros_like(value)
                kept[mask] = value[mask]
                final_info[key], final_info[f"_{key}"] = kept, mask
        for i in np.flatnonzero(done):
            self._reset_one(i)
        infos = self._infos(np.ones(n, dtype=bool))
        infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
        infos["final_info"], infos["_final_info"] = final_info, done.copy()
        return infos

    # ---------------------------------------------------------------------------- helpers
    def _infos(self, mask: np.ndarray, reasons: np.ndarray | None = None) -> dict[str, Any]:
        """Batched info (each key with its ``_key`` mask, as :class:`SyncVectorEnv` builds)."""
        Y = self._Y
        values: dict[str, np.ndarray] = {
            "object_pose": Y[:, X_OBJ : TH_OBJ + 1],
            "deformation": Y[:, DN_1 : DT_2 + 1],
            "constraint_error": self._ce,
            "grasped": self._grasped,
            "is_success": self._success,
            "setpoint": self._U,
            "physics_flags": self._flags,
        }
        if self.task.goal_dim:
            values["goal"] = self._goal
        for k, name in enumerate(self.task.terms):
            values[name] = self._terms[k]
        infos: dict[str, Any] = {}
        full = bool(mask.all())
        for key, value in values.items():
            if full:
                infos[key] = value.copy()
            else:
                infos[key] = np.zeros_like(value)
                infos[key][mask] = value[mask]
            infos[f"_{key}"] = mask.copy()
        if reasons is not None and any(r is not None for r in reasons):
            infos["termination_reason"] = reasons
            infos["_termination_reason"] = np.array([r is not None for r in reasons])
        return infos

    @property
    def goals(self) -> np.ndarray:
        """Current goals (SI), shape (N, goal_dim)."""
        return self._goal.copy()

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One RGB frame per environment (``render_mode="rgb_array"``), else None."""
        if self.render_mode is None:
            return None
        if self._renderer is None:
            from softhand_env.envs.rendering import SceneRenderer

            self._renderer = SceneRenderer(self.config.params, *self.config.render_size)
        frames = []
        for i in range(self.num_envs):
            pose = self.task.goal_pose(self._Y[i], self._goal[i])
            frames.append(self._renderer.frame(self._Y[i], self._U[i], self._params[i], pose))
        return tuple(frames)

    def close_extras(self, **kwargs: Any) -> None:
        self._renderer = None
