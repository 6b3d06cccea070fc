"""Transient analysis of the contact friction ratio over fixed windows of physical time.

The environments judge slip on the contact impulses of a control step (|J_t| / J_n over the
step, :mod:`softhand_env.physics.friction`), so the check coarsens as the control period grows.
This tool measures how the friction a motion needs depends on the length of the window it is
judged on, independently of the period the motion was commanded at:

1. :func:`record_episode` plays a policy in an environment at its own control period and
   records the applied set-points of every step (``info["setpoint"]``) and the object pose;
2. :func:`replay_fine` replays the same set-points in the same environment (same id,
   keywords and seed, so the same start, parameters and goal) at a fine control period
   (``control_dt`` = 1 ms, ``action_mode="absolute"``, set-points held) and collects the
   contact impulses (J_n1, J_n2, J_t1, J_t2) of every fine step from ``info["contact_impulse"]``.
   Splitting a control step into fine steps runs the same RK4 substeps with the same
   set-points, so the replay reproduces the original trajectory; the replay checks that
   (:attr:`FineReplay.pose_error`);
3. :func:`window_ratios` sums the fine impulses over windows of w ms of physical time, tiled
   from the episode start (the windows a window-by-window check would use) and sliding (every
   alignment: the worst case), and :func:`analyse` reports per window length the largest
   ratio, the episodes beyond their friction coefficient mu (a window with J_n < 0, tension,
   counts as beyond), and how long after the last set-point jump the peak window ends.

Run ``python -m softhand_env.tools.slip_windows`` for the paper's motions 1-8 (§5.5.1, each
held 1 s, through ``SoftHand-v0`` at 20 ms) and the time constants of the contact and the
PID loop (Table 5.1). Policies that live outside the package (scripted baselines, trained
agents) are recorded by ``benchmarks/slip_windows_agents.py`` with the same functions.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Window lengths of the analysis (ms).
WINDOWS_MS: tuple[int, ...] = (1, 2, 5, 10, 20, 40, 80, 160)
#: Control period of the replay (s).
FINE_DT = 1e-3


# ----------------------------------------------------------------------------- recording
@dataclass
class Recording:
    """One episode as played at its own control period.

    Attributes
    ----------
    env_id : str
        Registered id the episode ran in.
    env_kwargs : dict
        Every keyword of its base environment (``env.unwrapped.options``), wrappers excluded.
    seed : int
        ``reset(seed=...)`` of the episode.
    control_dt : float
        Control period of the play (s).
    setpoint0 : ndarray, shape (2,)
        Set-points at the reset (rad): the grasp set-points.
    setpoints : ndarray, shape (T, 2)
        Set-points applied during control step k (rad), ``info["setpoint"]``.
    poses : ndarray, shape (T + 1, 3)
        Object pose (x, y, theta; m, m, rad) at the reset and after every step.
    step_ratio : float
        Largest ``info["friction_ratio"]`` of the play (its own control steps; inf: tension).
    reason : str or None
        Termination reason of the last step.
    mu : float
        Friction coefficient of the episode (the hand's ``mu``, randomised on Random ids).
    options : dict or None
        ``reset`` options of the episode (e.g. an explicit goal).
    """

    env_id: str
    env_kwargs: dict[str, Any]
    seed: int
    control_dt: float
    setpoint0: np.ndarray
    setpoints: np.ndarray
    poses: np.ndarray
    step_ratio: float
    reason: str | None
    mu: float
    options: dict[str, Any] | None = None


class HeldSetpoints:
    """A set-point schedule with the Stable-Baselines3 ``predict`` signature.

    Parameters
    ----------
    setpoints : array_like, shape (M, 2)
        Set-point pairs (rad), each held for ``steps_each`` control steps.
    steps_each : int
        Control steps per pair.

    For environments made with ``action_mode="absolute"`` and ``normalize_action=False`` (the
    action is the set-point pair in rad). ``state`` is the step counter.
    """

    def __init__(self, setpoints: Any, steps_each: int):
        self.setpoints = np.asarray(setpoints, dtype=np.float64).reshape(-1, 2)
        if int(steps_each) < 1:
            raise ValueError(f"steps_each must be >= 1 (got {steps_each!r})")
        self.steps_each = int(steps_each)
        #: Control steps of the whole schedule.
        self.episode_steps = self.steps_each * len(self.setpoints)

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, int]:
        """Set-points (rad, shape (2,)) of the next step and the new step counter."""
        k = 0 if state is None or (episode_start is not None and np.all(episode_start)) \
            else int(state)
        row = min(k // self.steps_each, len(self.setpoints) - 1)
        return self.setpoints[row].copy(), k + 1


def record_episode(env: Any, policy: Any, seed: int, options: dict[str, Any] | None = None,
                   deterministic: bool = True) -> Recording:
    """Play one episode of ``policy`` (anything with the SB3 ``predict(obs, state,
    episode_start, deterministic)``) in ``env`` (a Gymnasium env, wrappers allowed, made by
    ``gym.make`` from a registered soft-hand id) from ``reset(seed=seed, options=options)``
    until it terminates or is truncated; returns its :class:`Recording`."""
    base = env.unwrapped
    obs, info = env.reset(seed=seed, options=options)
    setpoint0 = np.array(info["setpoint"], dtype=np.float64)
    setpoints, poses = [], [np.array(info["object_pose"])]
    state, start = None, np.array([True])
    ratio = 0.0
    while True:
        action, state = policy.predict(obs, state, start, deterministic)
        start = np.array([False])
        obs, _, terminated, truncated, info = env.step(action)
        setpoints.append(np.array(info["setpoint"], dtype=np.float64))
        poses.append(np.array(info["object_pose"]))
        ratio = max(ratio, float(np.max(info["friction_ratio"])))
        if terminated or truncated:
            break
    return Recording(
        env_id=env.spec.id, env_kwargs=base.options.as_dict(), seed=int(seed),
        control_dt=float(base.dt), setpoint0=setpoint0, setpoints=np.array(setpoints),
        poses=np.array(poses), step_ratio=ratio, reason=info.get("termination_reason"),
        mu=float(base.physics.params.mu), options=options)


# -------------------------------------------------------------------------------- replay
@dataclass
class FineReplay:
    """A :class:`Recording` replayed at a fine control period.

    Attributes
    ----------
    dt : float
        Fine control period (s).
    impulse : ndarray, shape (K, 4)
        (J_n1, J_n2, J_t1, J_t2) of every fine step (N s); K = T * (control_dt / dt).
    jumps : ndarray of int, shape (J,)
        Fine-step indices at which a new set-point takes effect (the first set-point counts if
        it differs from the reset's).
    max_dn : ndarray, shape (K,)
        Larger normal deformation d_n of the two fingertips at the end of each fine step (m).
    pose_error : float
        Largest |pose difference| (m and rad alike) between the replay at the ends of the
        original control steps and the original's poses.
    reason : str or None
        First termination reason the fine steps report (slip and tension are not checked in
        the replay: ``terminate_on_slip=False``; over-compression etc. now at every fine step).
    reason_time : float or None
        Physical time of that step's end (s).
    """

    dt: float
    impulse: np.ndarray
    jumps: np.ndarray
    max_dn: np.ndarray
    pose_error: float
    reason: str | None = None
    reason_time: float | None = None
    mu: float = 1.0
    meta: dict[str, Any] = field(default_factory=dict)


def replay_kwargs(rec: Recording, fine_dt: float = FINE_DT) -> dict[str, Any]:
    """``gym.make`` keywords of the fine replay: the play's keywords with the control period
    ``fine_dt``, set-points as actions in rad, no slip termination or success termination, no
    set-point latency (the applied set-points are replayed) and no observation noise."""
    kw = dict(rec.env_kwargs)
    kw.update(control_dt=fine_dt, action_mode="absolute", normalize_action=False,
              terminate_on_slip=False, setpoint_latency=0, obs_noise=0.0, history_len=1,
              render_mode=None)
    if kw.get("terminate_on_success") is not None or kw.get("task", "none") != "none":
        kw["terminate_on_success"] = False
    return kw


def replay_fine(rec: Recording, fine_dt: float = FINE_DT) -> FineReplay:
    """Replay ``rec``'s set-points at the control period ``fine_dt`` (s; ``rec.control_dt``
    must be a whole multiple of it), each held for its original control step.

    The environment is ``gym.make(rec.env_id, **replay_kwargs(rec, fine_dt))`` reset with the
    recording's seed and options; it is stepped through its base environment (``unwrapped``)
    so that the replay continues past a failure a fine step reports (the physics goes on; the
    first reason is kept in :attr:`FineReplay.reason`)."""
    import gymnasium as gym

    ratio = rec.control_dt / fine_dt
    n_fine = round(ratio)
    if n_fine < 1 or abs(ratio - n_fine) > 1e-9 * ratio:
        raise ValueError(f"control_dt {rec.control_dt} s is not a whole multiple of the fine "
                         f"period {fine_dt} s")
    env = gym.make(rec.env_id, **replay_kwargs(rec, fine_dt))
    base = env.unwrapped
    _, info = env.reset(seed=rec.seed, options=rec.options)
    err = float(np.max(np.abs(np.asarray(info["object_pose"]) - rec.poses[0])))
    T = len(rec.setpoints)
    impulse = np.empty((T * n_fine, 4))
    max_dn = np.empty(T * n_fine)
    reason, reason_time = None, None
    k = 0
    for t in range(T):
        u = rec.setpoints[t]
        for _ in range(n_fine):
            _, _, terminated, _, info = base.step(u)
            impulse[k] = info["contact_impulse"]
            max_dn[k] = max(info["deformation"][0], info["deformation"][1])
            k += 1
            if terminated and reason is None:
                reason, reason_time = info["termination_reason"], k * fine_dt
        err = max(err, float(np.max(np.abs(np.asarray(info["object_pose"]) - rec.poses[t + 1]))))
    env.close()
    prev = np.vstack([rec.setpoint0, rec.setpoints[:-1]])
    changed = np.flatnonzero(np.any(rec.setpoints != prev, axis=1))
    return FineReplay(dt=fine_dt, impulse=impulse, jumps=changed * n_fine, max_dn=max_dn,
                      pose_error=err, reason=reason, reason_time=reason_time, mu=rec.mu)


# ------------------------------------------------------------------------------- windows
def ratio_of(impulse: np.ndarray) -> np.ndarray:
    """Friction ratio of impulses (..., 4): max over the fingers of |J_t| / J_n, inf where
    a J_n <= 0 (as :func:`softhand_env.physics.friction.friction_ratio`); shape (...)."""
    from softhand_env.physics.friction import friction_ratio

    return friction_ratio(impulse).max(axis=-1)


def window_impulses(impulse: np.ndarray, m: int, sliding: bool = False) -> tuple[np.ndarray,
                                                                                 np.ndarray]:
    """Impulses summed over windows of ``m`` fine steps.

    Parameters
    ----------
    impulse : ndarray, shape (K, 4)
        Fine-step impulses (N s).
    m : int
        Window length in fine steps (>= 1).
    sliding : bool
        False: windows tiled from step 0 (the last one may be shorter); True: every window of
        m consecutive steps (K - m + 1 of them; one window of all steps if K < m).

    Returns
    -------
    sums : ndarray, shape (W, 4)
        Window impulses (N s).
    ends : ndarray of int, shape (W,)
        Fine-step index one past each window's last step.
    """
    K = len(impulse)
    if m < 1:
        raise ValueError(f"window length must be >= 1 fine step (got {m})")
    cs = np.vstack([np.zeros((1, 4)), np.cumsum(impulse, axis=0)])
    if sliding:
        ends = np.arange(min(m, K), K + 1)
        starts = np.maximum(ends - m, 0)
    else:
        ends = np.append(np.arange(m, K + 1, m), K) if K % m else np.arange(m, K + 1, m)
        starts = np.append(0, ends[:-1])
    return cs[ends] - cs[starts], ends


@dataclass(frozen=True)
class WindowStats:
    """Friction over windows of one length, for a set of episodes (one source).

    Attributes
    ----------
    window_ms : float
    peak : float
        Largest window ratio over all episodes (tiled windows; inf if a window pulled).
    peak_sliding : float
        The same over every alignment of the window (sliding windows).
    finite_peak : float
        Largest finite tiled-window ratio.
    median_episode_peak : float
        Median over the episodes of each episode's largest tiled-window ratio.
    n_exceed, n_tension, n_episodes : int
        Episodes with a tiled window beyond their mu (tension included), with a window in
        tension (J_n < 0), and episodes in all.
    n_exceed_sliding : int
        Episodes beyond their mu in some alignment.
    lag_ms : float
        Median over the exceeding episodes (all episodes if none exceed) of the time from the
        last set-point jump (or the episode start) before the peak window's end to that end
        (ms).
    peak_force_fraction : float
        Median over the same episodes of the peak window's mean normal force (the smaller of
        the two fingers, J_n / w) divided by the episode's median window normal force.
    """

    window_ms: float
    peak: float
    peak_sliding: float
    finite_peak: float
    median_episode_peak: float
    n_exceed: int
    n_tension: int
    n_episodes: int
    n_exceed_sliding: int
    lag_ms: float
    peak_force_fraction: float


def analyse(replays: Sequence[FineReplay], windows_ms: Sequence[float] = WINDOWS_MS
            ) -> list[WindowStats]:
    """:class:`WindowStats` per window length (ms, whole multiples of the fine period) over
    ``replays`` (one source)."""
    out = []
    for w in windows_ms:
        peaks, peaks_s, finite, lags, fractions, exceed_lags, exceed_fr = [], [], [], [], [], [], []
        n_exceed = n_tension = n_exceed_s = 0
        for rp in replays:
            m = round(w * 1e-3 / rp.dt)
            if m < 1 or abs(m * rp.dt - w * 1e-3) > 1e-9:
                raise ValueError(f"window {w} ms is not a whole number of {rp.dt * 1e3} ms steps")
            sums, ends = window_impulses(rp.impulse, m)
            r = ratio_of(sums)
            r_s = ratio_of(window_impulses(rp.impulse, m, sliding=True)[0])
            i = int(np.argmax(r))
            peaks.append(float(r[i]))
            peaks_s.append(float(r_s.max()))
            fin = r[np.isfinite(r)]
            finite.append(float(fin.max()) if len(fin) else 0.0)
            jn = sums[:, :2].min(axis=1)
            tension = bool(np.any(sums[:, :2] < 0.0))
            n_tension += tension
            before = rp.jumps[rp.jumps < ends[i]]
            lag = (ends[i] - (before[-1] if len(before) else 0)) * rp.dt * 1e3
            med = float(np.median(jn))
            frac = float(jn[i] / med) if med > 0 else math.nan
            lags.append(lag)
            fractions.append(frac)
            if r[i] > rp.mu:
                n_exceed += 1
                exceed_lags.append(lag)
                exceed_fr.append(frac)
            n_exceed_s += bool(r_s.max() > rp.mu)
        use_l, use_f = (exceed_lags, exceed_fr) if exceed_lags else (lags, fractions)
        out.append(WindowStats(
            window_ms=float(w), peak=max(peaks), peak_sliding=max(peaks_s),
            finite_peak=max(finite), median_episode_peak=float(np.median(peaks)),
            n_exceed=n_exceed, n_tension=n_tension, n_episodes=len(replays),
            n_exceed_sliding=n_exceed_s, lag_ms=_nanmedian(use_l),
            peak_force_fraction=_nanmedian(use_f)))
    return out


def _nanmedian(values: Sequence[float]) -> float:
    a = np.asarray(values, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if len(a) else math.nan


def _fmt(v: float) -> str:
    return "inf" if math.isinf(v) else ("-" if math.isnan(v) else f"{v:.3g}")


def format_stats(title: str, stats: Sequence[WindowStats]) -> str:
    """A Markdown table of :func:`analyse`'s rows under a ``title`` line."""
    head = ("| window (ms) | peak ratio | finite peak | median ep. peak | episodes > mu | "
            "tension | peak, any alignment | > mu, any alignment | peak lag after jump (ms) | "
            "peak J_n / median |")
    lines = [title, "", head, "|" + "---|" * 10]
    for s in stats:
        lines.append(
            f"| {s.window_ms:g} | {_fmt(s.peak)} | {_fmt(s.finite_peak)} | "
            f"{_fmt(s.median_episode_peak)} | {s.n_exceed}/{s.n_episodes} | "
            f"{s.n_tension}/{s.n_episodes} | {_fmt(s.peak_sliding)} | "
            f"{s.n_exceed_sliding}/{s.n_episodes} | {_fmt(s.lag_ms)} | "
            f"{_fmt(s.peak_force_fraction)} |")
    return "\n".join(lines)


def format_checks(title: str, recordings: Sequence[Recording], replays: Sequence[FineReplay]
                  ) -> str:
    """One line on the play and the replay of a source: episodes, own-step friction peak,
    replay pose error, termination reasons, largest mid-step d_n."""
    reasons = sorted({str(r.reason) for r in recordings})
    fine = sorted({f"{rp.reason}@{rp.reason_time:.3f}s" for rp in replays if rp.reason})
    return (f"{title}: {len(recordings)} episodes at {recordings[0].control_dt * 1e3:g} ms; "
            f"own-step friction peak {_fmt(max(r.step_ratio for r in recordings))}; "
            f"play ends {reasons}; replay pose error max "
            f"{max(rp.pose_error for rp in replays):.2e}; largest d_n at 1 ms "
            f"{1e3 * max(float(rp.max_dn.max()) for rp in replays):.2f} mm; fine-step "
            f"failures {fine or 'none'}")


def run_source(make: Callable[[], Any], policy: Any, seeds: Sequence[int],
               options: Sequence[dict[str, Any] | None] | None = None,
               fine_dt: float = FINE_DT) -> tuple[list[Recording], list[FineReplay]]:
    """Record ``policy`` in a fresh env from ``make()`` on every seed, then replay each
    recording at ``fine_dt``."""
    recs, reps = [], []
    env = make()
    for k, seed in enumerate(seeds):
        rec = record_episode(env, policy, seed, None if options is None else options[k])
        recs.append(rec)
        reps.append(replay_fine(rec, fine_dt))
    env.close()
    return recs, reps


# ------------------------------------------------------------------------ time constants
def time_constants(params: Any = None, d_n: float = 0.007) -> dict[str, float]:
    """Time constants (s) of the contact and the PID loop for Table 5.1 (or ``params``).

    The fingertip's elastic energy (Eq 5.5) has the stiffnesses k_n = d2U/dd_n2 = 2 pi E d_n
    / cos^2(theta_p) and k_t = d2U/dd_t2 = 2 pi E b d_n (b the bending factor), evaluated at
    ``d_n`` (m; the default grasp holds about 7 mm) and theta_p = 0. Returned: ``tau_t`` =
    c_t / k_t and ``tau_n`` = c_n / k_n (relaxation of the viscoelastic fingertip),
    ``tau_deform`` = M_deform / c_t (inertial time of the deformation coordinates), ``tau_pid``
    = Kd / Kp (slow pole of the overdamped free finger under the PD part), ``tau_pid_loaded``
    = Kd / (Kp + k_n L^2) (the same with one fingertip's stiffness at the finger tip),
    ``tau_pid_fast`` = I_1 / Kd (fast pole).
    """
    from softhand_env.physics.params import HandParams

    p = params if params is not None else HandParams()
    k_n = 2 * math.pi * p.E * d_n
    k_t = 2 * math.pi * p.E * p.bending * d_n
    return {
        "d_n": d_n,
        "k_n": k_n,
        "k_t": k_t,
        "tau_t": p.c_t / k_t,
        "tau_n": p.c_n / k_n,
        "tau_deform": p.m_deform / p.c_t,
        "tau_pid": p.Kd / p.Kp,
        "tau_pid_loaded": p.Kd / (p.Kp + k_n * p.L**2),
        "tau_pid_fast": p.I_1 / p.Kd,
    }


def format_time_constants(tc: dict[str, float]) -> str:
    """A Markdown table of :func:`time_constants`."""
    rows = [
        ("fingertip stiffness k_n = k_t = 2 pi E d_n", f"{tc['k_n']:.0f} N/m"),
        ("tangential relaxation c_t / k_t", f"{tc['tau_t'] * 1e3:.1f} ms"),
        ("normal relaxation c_n / k_n", f"{tc['tau_n'] * 1e3:.1f} ms"),
        ("deformation inertia M_deform / c_t", f"{tc['tau_deform'] * 1e3:.2f} ms"),
        ("PID slow pole Kd / Kp (free finger)", f"{tc['tau_pid'] * 1e3:.1f} ms"),
        ("PID slow pole Kd / (Kp + k_n L^2)", f"{tc['tau_pid_loaded'] * 1e3:.1f} ms"),
        ("PID fast pole I / Kd", f"{tc['tau_pid_fast'] * 1e6:.1f} us"),
    ]
    lines = [f"Time constants at d_n = {tc['d_n'] * 1e3:g} mm (Table 5.1)", "",
             "| quantity | value |", "|---|---|"]
    lines += [f"| {a} | {b} |" for a, b in rows]
    return "\n".join(lines)


# ----------------------------------------------------------------------------------- CLI
def paper_motions(duration: float = 1.0, control_dt: float = 0.02
                  ) -> tuple[Callable[[], Any], HeldSetpoints]:
    """Env factory and schedule of the paper's motions 1-8 through ``SoftHand-v0`` (from the
    parallel point-contact start, each pair held ``duration`` s at ``control_dt`` s)."""
    import gymnasium as gym

    import softhand_env  # noqa: F401  (registers the ids)
    from softhand_env.physics.motions import PAPER_MOTIONS_DEG

    steps = max(1, round(duration / control_dt))
    policy = HeldSetpoints(np.radians(PAPER_MOTIONS_DEG), steps)

    def make() -> Any:
        return gym.make("SoftHand-v0", action_mode="absolute", normalize_action=False,
                        grasp_duration=0.0, control_dt=control_dt,
                        max_episode_steps=policy.episode_steps)

    return make, policy


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point: the paper's motions 1-8 and the time constants."""
    ap = argparse.ArgumentParser(prog="python -m softhand_env.tools.slip_windows",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=float, nargs="+", default=list(WINDOWS_MS),
                    help="window lengths (ms), whole multiples of --fine-ms")
    ap.add_argument("--fine-ms", type=float, default=FINE_DT * 1e3,
                    help="control period of the replay (ms, default 1)")
    ap.add_argument("--duration", type=float, default=1.0,
                    help="seconds each paper motion is held (default 1)")
    ap.add_argument("--control-ms", type=float, default=20.0,
                    help="control period of the paper replay (ms, default 20)")
    args = ap.parse_args(argv)
    if not (args.fine_ms > 0 and args.duration > 0 and args.control_ms > 0):
        ap.error("--fine-ms, --duration and --control-ms must be > 0")
    print(format_time_constants(time_constants()))
    print()
    make, policy = paper_motions(args.duration, args.control_ms * 1e-3)
    recs, reps = run_source(make, policy, [0], fine_dt=args.fine_ms * 1e-3)
    title = (f"Paper motions 1-8 (SoftHand-v0, each held {args.duration:g} s, "
             f"{args.control_ms:g} ms steps)")
    print(format_stats(title, analyse(reps, args.windows)))
    print()
    print(format_checks("paper motions", recs, reps))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
