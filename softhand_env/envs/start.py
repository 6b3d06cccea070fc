"""Episode start: the paper's parallel point-contact state followed by a grasp phase.

:func:`start_episode` draws an episode's parameters, grasp set-points and goal from the env's
``np_random`` and returns its start state; both environments use it.

:func:`grasp_state` holds the grasp set-points for ``n_substeps`` RK4 substeps from
:func:`softhand_env.model.initial_state` (``n_substeps = 0`` returns the point-contact state
itself, as the paper's replay needs). Results are cached per (parameters, set-points, substeps),
so resets without randomisation cost a copy.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from softhand_env import kernel
from softhand_env.envs.config import EnvConfig
from softhand_env.envs.tasks import base_ratio, failure_state
from softhand_env.model import DN_1, DN_2, constraint_residuals, initial_state, pack_params
from softhand_env.params import HandParams
from softhand_env.physics import PhysicsError, describe_flags

_CACHE: OrderedDict[tuple, tuple[np.ndarray, float, float]] = OrderedDict()
_CACHE_SIZE = 64
#: Draws of randomised parameters / grasp noise tried before a failing grasp phase raises.
MAX_DRAWS = 10


def grasp_state(
    params: HandParams,
    prm: np.ndarray,
    setpoint: np.ndarray,
    n_substeps: int,
    ch_limit: float,
    dn_limit: float,
    use_cache: bool = True,
    base_limit: float = 1.0,
) -> tuple[np.ndarray, float, float]:
    """State after the grasp phase.

    Parameters
    ----------
    params : HandParams
        Parameters (for the point-contact geometry).
    prm : ndarray, shape (N_PARAMS,)
        ``pack_params(params)``.
    setpoint : ndarray, shape (2,)
        Grasp set-points (rad).
    n_substeps : int
        Duration of the grasp phase in RK4 substeps (0: no grasp phase).
    ch_limit : float
        Divergence bound on |C^H| (m).
    dn_limit : float
        Over-compression limit on d_n (m) the grasp must stay below.
    use_cache : bool
        Look up / store the result (off for randomised parameters, which rarely repeat).
    base_limit : float
        Contact past a fingertip base fails beyond this
        :func:`~softhand_env.envs.tasks.base_ratio` (as in the environments).

    Returns
    -------
    y : ndarray, shape (20,)
        A fresh copy of the post-grasp state.
    max_ch, max_cn : float
        Largest |C^H| (m) and |C^N| (m/s) over the grasp phase (0 without one).

    Raises
    ------
    PhysicsError
        The grasp phase left the model (lost grasp, over-compression, divergence, contact
        past the fingertip base): the configuration (parameters, grasp set-points) cannot
        start an episode.
    """
    u0, u1 = float(setpoint[0]), float(setpoint[1])
    limits = (float(ch_limit), float(dn_limit), float(base_limit))
    key = (prm.tobytes(), u0, u1, int(n_substeps), *limits)
    hit = _CACHE.get(key) if use_cache else None
    if hit is None:
        y = initial_state(params)
        max_ch = max_cn = 0.0
        if n_substeps > 0:
            diag = np.zeros(2)
            u = np.array([u0, u1])
            flags, _ = kernel.advance(y, u, prm, int(n_substeps), ch_limit, diag)
            if max(y[DN_1], y[DN_2]) >= dn_limit:
                flags |= kernel.FLAG_OVERCOMPRESSED
            if flags & kernel.FLAG_BASE and base_ratio(y, params.a) <= base_limit:
                flags &= ~kernel.FLAG_BASE  # within the tolerance: not a failure
            if flags & (kernel.FATAL_FLAGS | kernel.FLAG_BASE):  # the env's failures
                raise PhysicsError(
                    "the grasp phase at set-points "
                    f"{np.degrees(u).round(3).tolist()} deg failed: "
                    f"{', '.join(describe_flags(int(flags)))}; choose other grasp set-points "
                    "or parameters",
                    int(flags),
                )
            max_ch, max_cn = float(diag[0]), float(diag[1])
        hit = (y, max_ch, max_cn)
        if use_cache:
            _CACHE[key] = hit
            if len(_CACHE) > _CACHE_SIZE:
                _CACHE.popitem(last=False)
    return hit[0].copy(), hit[1], hit[2]


@dataclass(frozen=True)
class EpisodeStart:
    """Everything :func:`start_episode` draws and computes for one new episode.

    Attributes
    ----------
    params : HandParams
        Parameters of the episode (randomised or nominal).
    prm : ndarray, shape (N_PARAMS,)
        ``pack_params(params)``.
    setpoint : ndarray, shape (2,)
        First set-points (rad): the grasp set-points, with noise if configured.
    goal : ndarray, shape (goal_dim,)
        Goal (SI units).
    state : ndarray, shape (20,)
        Start state.
    constraint_error : ndarray, shape (2,)
        |C^H| max (m) and |C^N| max (m/s) at the start state.
    grasped, success : bool
        At the start state.
    """

    params: HandParams
    prm: np.ndarray
    setpoint: np.ndarray
    goal: np.ndarray
    state: np.ndarray
    constraint_error: np.ndarray
    grasped: bool
    success: bool


def start_episode(
    cfg: EnvConfig,
    rng: np.random.Generator,
    params: HandParams,
    prm: np.ndarray,
    goal: np.ndarray | None = None,
) -> EpisodeStart:
    """Draw and simulate the start of an episode (shared by the single and the vector env).

    ``rng`` draws, in this order: randomised parameters, grasp set-point noise, the goal. A
    randomised draw whose grasp phase fails (lost grasp, over-compression) is redrawn, up to
    :data:`MAX_DRAWS` times; then (and at once without randomisation) ``PhysicsError`` is raised.

    Parameters
    ----------
    cfg : EnvConfig
    rng : numpy Generator
        The environment's ``np_random``.
    params, prm : HandParams, ndarray
        Parameters of the previous episode (reused, not re-packed, when nothing is randomised).
    goal : ndarray, optional
        Goal to use instead of the sampled one (still sampled, to keep the stream aligned).
    """
    fixed = not (cfg.randomization.params_active or cfg.reset_noise > 0)
    for attempt in range(1 if fixed else MAX_DRAWS):
        new_params = cfg.randomization.sample_params(cfg.params, rng)
        if new_params is not params:
            params, prm = new_params, pack_params(new_params)
        u0 = cfg.grasp_setpoint.copy()
        if cfg.reset_noise > 0:
            u0 += rng.uniform(-cfg.reset_noise, cfg.reset_noise, size=2)
        try:
            y, _, _ = grasp_state(
                params, prm, u0, cfg.n_grasp, cfg.ch_limit, cfg.dn_limit, use_cache=fixed,
                base_limit=cfg.base_limit,
            )
            break
        except PhysicsError:
            if fixed or attempt == MAX_DRAWS - 1:
                raise
    sampled = cfg.task.sample_goal(rng)
    if goal is None:
        goal = sampled
    else:
        goal = np.asarray(goal, dtype=np.float64).reshape(-1)
        if goal.shape != sampled.shape or not np.isfinite(goal).all():
            raise ValueError(f"goal must be {sampled.size} finite numbers (SI units)")
    res = np.empty(4)
    constraint_residuals(y, prm, res)
    ce = np.array((max(abs(res[0]), abs(res[1])), max(abs(res[2]), abs(res[3]))))
    _, grasped, _, _ = failure_state(0, y, cfg.dn_limit)
    _, success = cfg.task.evaluate(y, tuple(float(g) for g in goal), 0.0, False, grasped)
    return EpisodeStart(params, prm, u0, goal, y, ce, bool(grasped), bool(success))
