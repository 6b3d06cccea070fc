"""Goal curriculum: widen the goal range during training.

The goal tasks draw goals uniformly from ``goal_scale`` times their ranges
(:meth:`softhand_env.envs.tasks.GoalTask.set_goal_scale`, 1 = the configured ranges). The
task is the env's public ``task`` attribute, shared by the N environments of the native vector
env, so one call changes every environment from its next reset:

* Gymnasium: ``env.unwrapped.task.set_goal_scale(0.3)`` (single or native vector env);
* SB3: :func:`set_goal_scale` on a ``DummyVecEnv`` or a
  :class:`~agents.sb3.native_vec_env.NativeVecEnv` (under any ``VecEnvWrapper``, e.g.
  ``VecNormalize``); ``SubprocVecEnv`` keeps its envs in other processes and is refused;
* during ``model.learn``: :class:`GoalCurriculumCallback` (a linear schedule), which logs
  ``curriculum/goal_scale``.
"""

from __future__ import annotations

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import SubprocVecEnv, VecEnv, VecEnvWrapper


def set_goal_scale(venv: VecEnv, scale: float) -> None:
    """Goal scale ``scale`` in (0, 1] for every environment of an in-process SB3 VecEnv.

    Raises
    ------
    ValueError
        ``scale`` out of range, a ``SubprocVecEnv``, or a task without goals.
    """
    base = venv
    while isinstance(base, VecEnvWrapper):
        base = base.venv
    if isinstance(base, SubprocVecEnv):
        raise ValueError("set_goal_scale needs an in-process VecEnv (vec_env dummy or native); "
                         "SubprocVecEnv's environments live in other processes")
    tasks = {id(t): t for t in venv.get_attr("task")}
    for task in tasks.values():
        if not hasattr(task, "set_goal_scale"):
            raise ValueError(f"task {task.name!r} has no goal to scale")
        task.set_goal_scale(scale)


class GoalCurriculumCallback(BaseCallback):
    """Goal scale from ``start`` to 1, linear in the fraction of training done, reaching 1 at
    ``until`` (e.g. 0.5 = halfway); set at the start of every rollout.

    Parameters
    ----------
    start : float
        Initial goal scale, in (0, 1].
    until : float
        Fraction of ``total_timesteps`` at which the scale reaches 1, in (0, 1].
    """

    def __init__(self, start: float = 0.2, until: float = 0.5, verbose: int = 0):
        super().__init__(verbose)
        for name, value in (("start", start), ("until", until)):
            if not (isinstance(value, (int, float)) and 0.0 < value <= 1.0):
                raise ValueError(f"{name} must be a number in (0, 1] (got {value!r})")
        self.start, self.until = float(start), float(until)
        self.scale = self.start
        self._total = 1

    def _on_training_start(self) -> None:
        self._total = max(int(self.locals.get("total_timesteps", 0)), 1)
        self._apply()

    def _on_rollout_start(self) -> None:
        self._apply()

    def _apply(self) -> None:
        done = min(self.num_timesteps / (self.until * self._total), 1.0)
        self.scale = self.start + (1.0 - self.start) * done
        set_goal_scale(self.training_env, self.scale)
        self.logger.record("curriculum/goal_scale", self.scale)

    def _on_step(self) -> bool:
        return True

    def __repr__(self) -> str:
        return f"GoalCurriculumCallback(start={self.start}, until={self.until})"


__all__ = ["GoalCurriculumCallback", "set_goal_scale"]
