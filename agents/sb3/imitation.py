"""What a teacher-student distillation shares with every student: the observation views of
teacher and student on one rollout (:func:`view_layout`, :func:`rollout_layout`,
:func:`teacher_view`, :func:`blind_view`), the keywords in which they may differ
(:data:`PAIR_KEYS`), the imitation loss (:func:`imitation_loss`) and its step-size schedule
(:func:`lr_at`), and the validation of a student on the validation goals (:func:`validate`).
The library of ``agents.distill`` (an SB3 student) and ``agents.recurrent_distill`` (a
recurrent one)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from agents.common.cli import UserError
from agents.common.metrics import final_errors, is_failure, strict_success, summarize
from agents.sb3.interrupts import DeferredSignals
from agents.sb3.training import rewind_validation
from softhand_env.envs.observation import ObservationLayout

#: Dict-observation key of the blind part (what the student reads).
BLIND_KEY = "observation"
#: Observation keywords in which the student may read more than its teacher (its observation
#: then contains the teacher's: more frames of history, tactile entries added to each frame).
VIEW_KEYS = ("history_len", "obs_mode", "onset_obs")
#: Action keywords in which student and teacher may differ: the teacher acts in the student's
#: env, so a student with a set-point ramp of its own is labelled by a teacher acting with it.
ACTUATION_KEYS = ("setpoint_ramp_ms",)
#: The keywords in which student and teacher may differ besides the reward's.
PAIR_KEYS = (*VIEW_KEYS, *ACTUATION_KEYS)


def view_layout(kwargs: dict[str, Any]) -> ObservationLayout:
    """The frame layout (grasp-onset entries included, goal entries left out) of env keywords
    ``kwargs``."""
    return ObservationLayout(kwargs.get("obs_mode", "proprio"), kwargs.get("history_len", 1), (),
                             onset=bool(kwargs.get("onset_obs", False)))


def teacher_view(obs: dict[str, np.ndarray], teacher: ObservationLayout,
                 student: ObservationLayout, teacher_size: int | None = None
                 ) -> dict[str, np.ndarray]:
    """The teacher's Dict observation from the student env's.

    The blind part, (B, student.history_size + rest), keeps the newest ``teacher.history_len``
    frames (frames are newest first), of each frame its first ``teacher.frame_size`` entries
    (the proprio entries precede the tactile ones), the grasp-onset entries if the teacher
    reads them (``onset_obs``), and what follows (goal, wrapper features) up to the teacher's
    blind size ``teacher_size`` (all of it when None: the features of wrappers the student has
    beyond the teacher's come last); the other keys are shared.
    """
    blind = obs[BLIND_KEY]
    view = blind_view(blind, teacher, student, teacher_size)
    return obs if view is blind else {**obs, BLIND_KEY: view}


def blind_view(blind: np.ndarray, view: ObservationLayout, source: ObservationLayout,
               size: int | None = None) -> np.ndarray:
    """The blind observation of layout ``view`` (blind size ``size``) contained in ``blind``,
    one of layout ``source`` (:func:`teacher_view`'s rule; ``blind`` itself when they are the
    same)."""
    if view.onset and not source.onset:
        raise ValueError("the view reads the grasp-onset entries, its source has none")
    same_frames = (view.history_len, view.frame_size, view.onset) == (
        source.history_len, source.frame_size, source.onset)
    if same_frames and size in (None, blind.shape[-1]):
        return blind
    lead = blind.shape[:-1]
    frames = blind[..., : source.history_size].reshape(*lead, source.history_len,
                                                        source.frame_size)
    kept = frames[..., : view.history_len, : view.frame_size].reshape(*lead, view.history_size)
    onset = blind[..., source.history_size: source.history_size + view.onset_size]
    rest = blind[..., source.blind_size:]
    if size is not None:
        rest = rest[..., : size - view.blind_size]
    return np.concatenate([kept, onset, rest], axis=-1)


def rollout_layout(student: ObservationLayout, teacher: ObservationLayout,
                   blind_teacher: bool) -> ObservationLayout:
    """The frame layout the DAgger rollouts run: the student's, or with a blind teacher the
    union of both (the longer history; tactile and grasp-onset entries if either reads them),
    from which each
    policy reads its own view (:func:`blind_view`)."""
    if not blind_teacher:
        return student
    frames = student if student.tactile or not teacher.tactile else teacher
    return view_layout({"obs_mode": frames.obs_mode,
                        "history_len": max(student.history_len, teacher.history_len),
                        "onset_obs": student.onset or teacher.onset})


def validate(model: Any, venv: Any, targets: Sequence[str], eval_seed: int,
             stop: DeferredSignals | None = None) -> dict[str, float]:
    """Success, strict success (``success_strict``, within 0.5 mm / 0.5 deg), the rate of
    episodes ended by a physical failure (``failure_rate``) and final errors
    of the deterministic student on goals ``eval_seed + k`` (env k of the native SB3 vector env
    ``venv``, re-seeded here; the first episode of each). ``stop``: checked before every step
    (:class:`~agents.sb3.interrupts.Interrupted` once a signal was received)."""
    n_eval = venv.num_envs
    rewind_validation(venv, eval_seed)
    obs = venv.reset()
    finished: dict[int, dict[str, Any]] = {}
    while len(finished) < n_eval:
        if stop is not None:
            stop.check()
        action, _ = model.predict(obs, deterministic=True)
        obs, _, dones, infos = venv.step(action)
        for i in np.flatnonzero(dones):
            finished.setdefault(int(i), infos[i])
    infos = [finished[i] for i in range(n_eval)]
    successes = [bool(info.get("is_success", False)) for info in infos]
    errors = [final_errors(info, targets) for info in infos]
    summary = summarize(targets, successes, errors)
    summary["success_strict"] = float(np.mean(
        [strict_success(ok, err, targets) for ok, err in zip(successes, errors, strict=True)]))
    summary["failure_rate"] = float(np.mean(
        [is_failure(info.get("termination_reason")) for info in infos]))
    return summary


def imitation_loss(pred: Any, label: Any, squeeze_expectile: float = 0.5) -> Any:
    """The DAgger fit's loss (torch scalar) of the student's mean actions ``pred`` against the
    teacher's ``label`` (torch (B, act_dim), the normalised action space).

    With ``squeeze_expectile`` tau = 0.5 the mean squared error. Otherwise the two-finger
    action is written in the orthonormal (rotate, squeeze) coordinates r = (a_1 - a_2) / sqrt 2,
    s = (a_1 + a_2) / sqrt 2 (s > 0 closes both fingers; the finger actions share one range)
    and the squeeze error u = s_label - s_pred is weighted 2 tau where u >= 0 (the student
    closes less than the label) and 2 (1 - tau) where u < 0 (it closes more): the minimiser is
    the tau-expectile of the labels' squeeze in a state, which for tau < 0.5 lies below their
    mean where states the student cannot tell apart carry different labels, and equals the
    label where they do not. The rotate error is squared as is; the sum is divided by
    ``act_dim`` like the mean squared error, which tau = 0.5 reproduces exactly."""
    err = label - pred
    if squeeze_expectile == 0.5:
        return (err ** 2).mean()
    if err.shape[-1] != 2:
        raise UserError(f"--squeeze-expectile needs the two-finger action (got {err.shape[-1]} "
                        "action components)")
    rotate = (err[:, 0] - err[:, 1]) / 2 ** 0.5
    squeeze = (err[:, 0] + err[:, 1]) / 2 ** 0.5
    weight = 2 * (squeeze_expectile * (squeeze >= 0) + (1 - squeeze_expectile) * (squeeze < 0))
    return (rotate ** 2 + weight * squeeze ** 2).mean() / 2


def lr_at(k: int, iterations: int, lr: float, lr_final: float) -> float:
    """Adam step size at iteration ``k`` of ``iterations``: linear from ``lr`` (k = 0) to
    ``lr_final`` (k = iterations - 1)."""
    frac = k / (iterations - 1) if iterations > 1 else 0.0
    return lr + (lr_final - lr) * frac
