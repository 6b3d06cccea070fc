"""Episode start: the paper's parallel point-contact state followed by a grasp phase.

:func:`start_episode` draws an episode's parameters, grasp set-points and goal from the env's
``np_random`` and returns its start state; :func:`start_episodes` does the same for K episodes
at once (what both environments call), drawing only the goals (and latencies) row by row when
every episode starts from the one cached grasp state, and otherwise simulating the K grasp
phases in one batched physics (:func:`grasp_states`).

:func:`grasp_state` holds the grasp set-points for ``n_substeps`` RK4 substeps from the
paper's parallel point-contact state (``n_substeps = 0`` returns that state itself, as the
paper's replay needs) and classifies the result like every control step
(:func:`softhand_env.physics.failure.classify`, through :class:`~softhand_env.physics.HandPhysics`).
Results are cached per (parameters, set-points, substeps, limits): every field of
:class:`~softhand_env.physics.params.HandParams` and every argument of :func:`grasp_state` is
part of the key, so a cached state is the one the grasp phase would compute, bit for bit.
Resets without randomisation (nominal parameters, no grasp noise) therefore simulate the grasp
phase once per process and then cost a copy; randomised resets simulate it every time.
:func:`grasp_cache` switches the cache off (e.g. to check that it changes nothing).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any, NamedTuple

import numpy as np

from softhand_env.envs.config import EnvConfig
from softhand_env.physics.hand import HandPhysics, PhysicsError
from softhand_env.physics.model import NY
from softhand_env.physics.params import HandParams

_CACHE: OrderedDict[tuple[Any, ...], tuple[np.ndarray, float, float]] = OrderedDict()
_CACHE_SIZE = 64
_CACHE_ON = [True]
#: Draws of randomised parameters / grasp noise tried before a failing grasp phase raises.
MAX_DRAWS = 10


@contextmanager
def grasp_cache(enabled: bool) -> Iterator[None]:
    """Within the ``with`` block, :func:`start_episode` uses the grasp cache (``True``, the
    default outside) or simulates every grasp phase (``False``); the cache's content is kept."""
    previous = _CACHE_ON[0]
    _CACHE_ON[0] = bool(enabled)
    try:
        yield
    finally:
        _CACHE_ON[0] = previous


def grasp_state(
    params: HandParams,
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
        Parameters of the hand.
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
        Allowed reach of a contact circle past its fingertip base (as in the environments).

    Returns
    -------
    y : ndarray, shape (20,)
        A fresh copy of the post-grasp state.
    max_ch, max_cn : float
        Largest |C^H| (m) and |C^N| (m/s) over the grasp phase (0 without one).

    Raises
    ------
    PhysicsError
        The grasp phase ended in a failure (lost grasp, over-compression, divergence, contact
        past the fingertip base): the configuration (parameters, grasp set-points) cannot
        start an episode.
    """
    u0, u1 = float(setpoint[0]), float(setpoint[1])
    key = (params, u0, u1, int(n_substeps), float(ch_limit), float(dn_limit), float(base_limit))
    hit = _CACHE.get(key) if use_cache else None
    if hit is None:
        physics = HandPhysics(
            params, ch_limit=ch_limit, dn_limit=dn_limit, base_limit=base_limit,
            check_stability=False,
        )
        if n_substeps > 0:
            status = physics.step(np.array([u0, u1]), int(n_substeps), strict=False)
            if status.failed:
                raise _grasp_failure(np.array([u0, u1]), status.reason, int(status.flags))
            hit = (physics.get_state(), float(status.max_ch), float(status.max_cn))
        else:
            hit = (physics.get_state(), 0.0, 0.0)
        if use_cache:
            _CACHE[key] = hit
            if len(_CACHE) > _CACHE_SIZE:
                _CACHE.popitem(last=False)
    return hit[0].copy(), hit[1], hit[2]


def _grasp_failure(setpoint: np.ndarray, reason: str, flags: int) -> PhysicsError:
    """The error of a grasp phase at set-points ``setpoint`` (2,) (rad) that ended in
    ``reason`` with kernel ``flags``."""
    return PhysicsError(
        "the grasp phase at set-points "
        f"{np.degrees(setpoint).round(3).tolist()} deg failed: "
        f"{reason}; choose other grasp set-points or parameters",
        flags,
    )


def grasp_states(
    params: Sequence[HandParams],
    setpoints: np.ndarray,
    n_substeps: int,
    ch_limit: float,
    dn_limit: float,
    base_limit: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, list[PhysicsError | None]]:
    """The grasp phases of K hands in one batched physics (no cache): hand k with parameters
    ``params[k]`` holds ``setpoints[k]`` for ``n_substeps`` substeps from the paper's parallel
    point-contact state; the same numbers as :func:`grasp_state` hand by hand.

    Parameters
    ----------
    params : sequence of K HandParams
        One integrator (and under ``"ros2"`` one ``dt`` / ``ros2_dt``) for all.
    setpoints : ndarray, shape (K, 2)
        Grasp set-points (rad).
    n_substeps, ch_limit, dn_limit, base_limit
        As for :func:`grasp_state` (``n_substeps`` >= 1).

    Returns
    -------
    y : ndarray, shape (K, 20)
        Post-grasp states (rows of failed hands are not start states).
    failed : ndarray of bool, shape (K,)
        Grasp phases that ended in a failure.
    errors : list of K PhysicsError or None
        The error :func:`grasp_state` raises for each failed hand.
    """
    k = len(params)
    physics = HandPhysics(params[0], num_hands=k, ch_limit=ch_limit, dn_limit=dn_limit,
                          base_limit=base_limit, check_stability=False)
    for i in range(1, k):
        if params[i] is not params[0]:
            physics.set_params(params[i], i)
    physics.reset()  # each hand from its own parallel point-contact state
    status = physics.step(setpoints, int(n_substeps), strict=False)
    failed = np.array(status.failed, dtype=bool)
    errors: list[PhysicsError | None] = [
        _grasp_failure(setpoints[i], status.reason[i], int(status.flags[i])) if failed[i]
        else None for i in range(k)
    ]
    return physics.get_state(), failed, errors


def _nominal_start(cfg: EnvConfig) -> bool:
    """True when every episode of ``cfg`` starts from the same grasp phase: nominal
    parameters (nothing randomised) and no grasp set-point noise (its result is cached)."""
    return not (cfg.randomization.params_active or cfg.reset_noise > 0)


class EpisodeStart(NamedTuple):
    """Everything :func:`start_episode` draws and computes for one new episode.

    Attributes
    ----------
    params : HandParams
        Parameters of the episode (randomised or nominal).
    setpoint : ndarray, shape (2,)
        First set-points (rad): the grasp set-points, with noise if configured.
    goal : ndarray, shape (goal_dim,)
        Goal (SI units).
    state : ndarray, shape (20,)
        Start state.
    latency : int
        Set-point latency of the episode (control steps; 0 unless ``setpoint_latency``).
    """

    params: HandParams
    setpoint: np.ndarray
    goal: np.ndarray
    state: np.ndarray
    latency: int = 0


def _draw_grasp(cfg: EnvConfig, rng: np.random.Generator) -> tuple[HandParams, np.ndarray]:
    """An episode's randomised parameters and grasp set-points (2,) (rad; with the grasp
    noise), drawn from ``rng`` in that order."""
    params = cfg.randomization.sample_params(cfg.params, rng)
    u0 = cfg.grasp_setpoint.copy()
    if cfg.reset_noise > 0:
        u0 += rng.uniform(-cfg.reset_noise, cfg.reset_noise, size=2)
    return params, u0


def start_episode(
    cfg: EnvConfig,
    rng: np.random.Generator,
    goal: Any = None,
) -> EpisodeStart:
    """Draw and simulate the start of an episode (shared by the single and the vector env).

    ``rng`` draws, in this order: randomised parameters of the dynamics, grasp set-point noise,
    the goal, the randomised friction coefficient (it does not change the grasp phase), then
    (only with ``setpoint_latency`` > 0) the episode's set-point latency. A
    randomised draw whose grasp phase fails (lost grasp, over-compression) is redrawn, up to
    :data:`MAX_DRAWS` times; then (and at once without randomisation) ``PhysicsError`` is raised.

    Parameters
    ----------
    cfg : EnvConfig
    rng : numpy Generator
        The environment's ``np_random``.
    goal : array_like, optional
        Goal to use instead of the sampled one (still sampled, to keep the stream aligned);
        ``ValueError`` unless it has one finite entry per target within the task's goal
        range (``goal_x_range_mm`` / ``goal_theta_range_deg``, in SI units).
    """
    fixed = _nominal_start(cfg)
    cached = fixed and _CACHE_ON[0]
    for attempt in range(1 if fixed else MAX_DRAWS):
        params, u0 = _draw_grasp(cfg, rng)
        try:
            y, _, _ = grasp_state(
                params, u0, cfg.n_grasp, cfg.ch_limit, cfg.dn_limit, use_cache=cached,
                base_limit=cfg.base_limit,
            )
            break
        except PhysicsError:
            if fixed or attempt == MAX_DRAWS - 1:
                raise
    sampled = cfg.task.sample_goal(rng)
    goal = sampled if goal is None else checked_goal(cfg, goal)
    params = cfg.randomization.sample_friction(params, rng)
    latency = 0
    if cfg.setpoint_latency > 0:
        latency = int(rng.integers(0, cfg.setpoint_latency + 1))
    return EpisodeStart(params, u0, goal, y, latency)


def checked_goal(cfg: EnvConfig, goal: Any) -> np.ndarray:
    """``goal`` as float (goal_dim,) (SI units); ``ValueError`` unless it has one finite entry
    per target of the task within its goal range."""
    size = len(cfg.task.targets)
    try:
        goal = np.asarray(goal, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"goal must be {size} finite numbers (SI units)") from None
    if goal.shape != (size,) or not np.isfinite(goal).all():
        raise ValueError(f"goal must be {size} finite numbers (SI units)")
    for target, g in zip(cfg.task.targets, goal, strict=True):
        if abs(g) > target.goal_range:
            raise ValueError(
                f"goal {target.name} = {float(g)!r} is outside the task's range "
                f"[-{target.goal_range:g}, {target.goal_range:g}] (SI units)"
            )
    return goal


class EpisodeStarts(NamedTuple):
    """:class:`EpisodeStart` of K episodes as arrays.

    Attributes
    ----------
    params : list of HandParams
        K parameter sets (the same object where they are the same).
    setpoint : ndarray, shape (K, 2)
        First set-points (rad).
    goal : ndarray, shape (K, goal_dim)
        Goals (SI units).
    state : ndarray, shape (K, 20)
        Start states.
    latency : ndarray of int64, shape (K,)
        Set-point latencies (control steps).
    mu : ndarray, shape (K,)
        Friction coefficients.
    radius : ndarray, shape (K,)
        Fingertip radii a (m).
    """

    params: list[HandParams]
    setpoint: np.ndarray
    goal: np.ndarray
    state: np.ndarray
    latency: np.ndarray
    mu: np.ndarray
    radius: np.ndarray


def _draw_goals(cfg: EnvConfig, rngs: Sequence[np.random.Generator],
                goals: Sequence[Any] | None) -> np.ndarray:
    """Goals (K, goal_dim) (SI) of K episodes, row k drawn from ``rngs[k]`` even where
    ``goals[k]`` is given (to keep the stream aligned), which then replaces it (checked)."""
    goal = cfg.task.sample_goals(rngs)
    if goals is not None:
        for j, g in enumerate(goals):
            goal[j] = checked_goal(cfg, g)
    return goal


def _draw_latencies(cfg: EnvConfig, rngs: Sequence[np.random.Generator]) -> np.ndarray:
    """Set-point latencies (K,) (int64, control steps) of K episodes, each drawn from its own
    generator with ``setpoint_latency`` > 0, else 0 without a draw."""
    latency = np.zeros(len(rngs), dtype=np.int64)
    if cfg.setpoint_latency > 0:
        for j, rng in enumerate(rngs):
            latency[j] = rng.integers(0, cfg.setpoint_latency + 1)
    return latency


def start_episodes(
    cfg: EnvConfig,
    rngs: Sequence[np.random.Generator],
    goals: Sequence[Any] | None = None,
) -> EpisodeStarts:
    """:func:`start_episode` of K episodes, episode k drawing from ``rngs[k]`` (its goal
    ``goals[k]`` if given): the same draws and numbers, bit for bit.

    Without randomisation (nominal parameters, no grasp noise) and with the grasp cache on,
    every episode starts from the one cached grasp state and only the goals (and latencies)
    are drawn, row by row; otherwise the K grasp phases run in one batched physics
    (:func:`_start_simulated`).
    """
    k = len(rngs)
    if not (_nominal_start(cfg) and _CACHE_ON[0]):
        if k > 1 and cfg.n_grasp > 0:
            return _start_simulated(cfg, rngs, goals)
        starts = [start_episode(cfg, rng, None if goals is None else goals[j])
                  for j, rng in enumerate(rngs)]
        params = [s.params for s in starts]
        return EpisodeStarts(
            params, np.array([s.setpoint for s in starts]).reshape(k, 2),
            np.array([s.goal for s in starts]).reshape(k, -1),
            np.array([s.state for s in starts]).reshape(k, -1),
            np.array([s.latency for s in starts], dtype=np.int64),
            np.array([p.mu for p in params]), np.array([p.a for p in params]),
        )
    prm = cfg.params
    y, _, _ = grasp_state(prm, cfg.grasp_setpoint, cfg.n_grasp, cfg.ch_limit, cfg.dn_limit,
                          base_limit=cfg.base_limit)
    goal = _draw_goals(cfg, rngs, goals)
    latency = _draw_latencies(cfg, rngs)
    mu, radius = np.empty(k), np.empty(k)
    mu.fill(prm.mu)
    radius.fill(prm.a)
    # ndarray.repeat and fill: the rows of np.tile / np.full, at a fraction of their call cost
    return EpisodeStarts([prm] * k, cfg.grasp_setpoint[None].repeat(k, 0), goal,
                         y[None].repeat(k, 0), latency, mu, radius)


def _start_simulated(
    cfg: EnvConfig,
    rngs: Sequence[np.random.Generator],
    goals: Sequence[Any] | None,
) -> EpisodeStarts:
    """:func:`start_episodes` with a grasp phase simulated per episode (randomised, or the
    cache off), the K phases in one batched physics (:func:`grasp_states`): each generator
    draws what :func:`start_episode` draws, in its order (parameters and grasp noise, again
    for a failed grasp phase, then goal, friction coefficient, latency), so the numbers are
    the same. On a failure that raises, the generators of the other episodes may have drawn
    their parameters already."""
    k = len(rngs)
    fixed = _nominal_start(cfg)
    params: list[HandParams] = [cfg.params] * k
    setpoints = np.empty((k, 2))
    states = np.empty((k, NY))
    pending = np.arange(k)
    for attempt in range(1 if fixed else MAX_DRAWS):
        for j in pending.tolist():
            params[j], setpoints[j] = _draw_grasp(cfg, rngs[j])
        y, failed, errors = grasp_states([params[j] for j in pending.tolist()],
                                         setpoints[pending], cfg.n_grasp, cfg.ch_limit,
                                         cfg.dn_limit, cfg.base_limit)
        states[pending[~failed]] = y[~failed]
        if failed.any() and (fixed or attempt == MAX_DRAWS - 1):
            error = errors[int(np.flatnonzero(failed)[0])]
            assert error is not None
            raise error
        pending = pending[failed]
        if pending.size == 0:
            break
    goal = _draw_goals(cfg, rngs, goals)
    params = [cfg.randomization.sample_friction(p, rng)
              for p, rng in zip(params, rngs, strict=True)]
    latency = _draw_latencies(cfg, rngs)
    return EpisodeStarts(params, setpoints, goal, states, latency,
                         np.array([p.mu for p in params]), np.array([p.a for p in params]))
