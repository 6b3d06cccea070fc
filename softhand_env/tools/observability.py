"""How blind is an environment? Regress the object's pose (or the fingertips' compression) from
the agent's observation frames.

::

    python -m softhand_env.tools.observability --env SoftHandPose-v0
    python -m softhand_env.tools.observability --env SoftHandPose-v1 --obs-mode proprio_tactile
    python -m softhand_env.tools.observability --env SoftHandPose-v0 --sensor-model realistic
    python -m softhand_env.tools.observability --env SoftHandPoseRandom-v0 \\
        --env-kwargs obs_mode:proprio_tactile obs_noise:0 --frames 1 4 --episodes 40

Rolls out ``--episodes`` episodes (``reset(seed=SEED + k)``) of a data-collection policy,
records every observation frame the agent would see (noise included; the goal entries and the
env's own history are left out) and the true object pose (x, y, theta) from
``info["object_pose"]``, splits the data by EPISODE into training and held-out episodes, fits
a small MLP (PyTorch) from the newest frame and from k stacked frames (newest first; the first
frame repeats before the episode start, as the env's ``history_len`` does) to the pose, and
prints a table: RMSE of x and y (mm) and theta (deg) on the held-out frames, and the fraction
of held-out frames whose x is within 1 mm AND theta within 1 deg (the benchmark's success
tolerances), and within 0.5 mm AND 0.5 deg (the strict precision tolerances). The row
``mean`` predicts the training mean pose: the spread the frames have to explain. The title
line names the sensing the frames were read with: the sensor model (``--sensor-model``,
default the id's: ``ideal`` on ``-v0``, ``realistic`` on ``-v1``;
:mod:`softhand_env.envs.sensors`), the observation mode (``--obs-mode``, default the id's
``proprio``) and the observation noise (``obs_noise``, scaled units; the ``Random`` ids' preset
0.01; ``--sensor-model ideal`` on a ``Random`` ``-v1`` id also turns its per-episode sensor
gains off). ``--env-kwargs KEY:VALUE`` sets any other ``gym.make`` keyword (values as YAML, read
with the bounded loader); a keyword given both ways is refused. A wrong input is one line
``error: ...`` on stderr and exit code 2 (:func:`softhand_env.cli.run_cli`).

Policies (both read nothing of the object; the tool may read the env, the regressor only sees
the frames):

* ``scripted`` (default): a smooth random set-point walk around the grasp. Every
  ``WALK_HOLD_S`` seconds it draws a new target pair (g + phi + s_1, g - phi + s_2), g the
  grasp set-point, phi ~ U(-10, 10) deg a common rotation (rolling the object over about
  +-13 mm and +-8 deg) and s_i ~ U(-1.5, 1) deg a per-finger squeeze offset (changing the
  grasp force and the roll), and moves the set-points towards it at most 25 deg/s. It runs in
  ``action_mode="absolute", normalize_action=False`` (set by the tool; the observation does
  not depend on the action mode). Episodes run to the env's time limit (or ``--max-steps``)
  unless they fail.
* ``random``: uniform samples of the env's own action space (seeded), with the env's action
  mode (delta by default: a random walk of the set-points by up to ``max_delta_deg`` per step,
  which ends most episodes early by over-compression or a lost grasp).

``--target compression`` regresses the fingertips' normal deformations d_n1, d_n2 (from
``info["deformation"]``) instead of the pose: the quantity the over-compression check judges
(d_n >= ``overcompression_ratio`` a ends an episode). Its table gives the RMSE (mm, both
fingers) on all held-out frames and on those compressed beyond 8.5 mm, the mean error there
(mm; negative: the fit reads a deep compression as shallower) and the fraction of frames with
both fingers within 0.5 mm. With ``--env-kwargs onset_obs:true`` each frame carries the two
grasp-onset entries too (the joint angles where the grasp began, constant in an episode).

The regression is seeded and deterministic (one torch thread). ``--shuffle-labels`` permutes
the training poses across frames: the fit then cannot learn anything, which is the sanity
check that the table measures information in the frames.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softhand_env.cli import ArgumentParser, CliError, one_line, parse_kv, run_cli
from softhand_env.envs.observation import OBS_MODES
from softhand_env.envs.sensors import SENSOR_MODELS

#: Success tolerances of the benchmark: x (m) and theta (rad).
X_TOL = 1e-3
THETA_TOL = math.radians(1.0)
#: Strict precision tolerances (strict success of the evaluations): x (m) and theta (rad).
X_TOL_STRICT = 0.5e-3
THETA_TOL_STRICT = math.radians(0.5)
#: Regression targets (``--target``).
TARGETS = ("pose", "compression")
#: Compressions (m) beyond which the compression table reports the error separately (the
#: over-compression limit is 10 mm at the nominal fingertip radius).
DEEP_DN = 8.5e-3
#: Compression tolerance (m) of the compression table's "within" column.
DN_TOL = 0.5e-3
#: Set-point walk: seconds between targets, largest rate (rad/s), ranges (rad).
WALK_HOLD_S = 0.2
WALK_RATE = math.radians(25.0)
WALK_ROTATION = math.radians(10.0)
WALK_SQUEEZE = (math.radians(-1.5), math.radians(1.0))
POLICIES = ("scripted", "random")


class SetpointWalk:
    """The ``scripted`` policy: a smooth random set-point walk (module doc).

    Parameters
    ----------
    grasp : array_like, shape (2,)
        Set-points at the reset (rad).
    dt : float
        Control period (s).
    rng : numpy.random.Generator
    """

    def __init__(self, grasp: Any, dt: float, rng: np.random.Generator):
        self.grasp = np.asarray(grasp, dtype=np.float64).copy()
        self.u = self.grasp.copy()
        self.rng = rng
        self.hold = max(1, round(WALK_HOLD_S / dt))
        self.max_step = WALK_RATE * dt
        self.target = self.grasp.copy()
        self.k = 0

    def __call__(self) -> np.ndarray:
        """Set-points (rad, shape (2,)) of the next control step."""
        if self.k % self.hold == 0:
            phi = self.rng.uniform(-WALK_ROTATION, WALK_ROTATION)
            s = self.rng.uniform(*WALK_SQUEEZE, size=2)
            self.target = self.grasp + np.array([phi, -phi]) + s
        self.k += 1
        self.u = self.u + np.clip(self.target - self.u, -self.max_step, self.max_step)
        return self.u.copy()


@dataclass
class Episodes:
    """Frames and poses of the rolled-out episodes.

    Attributes
    ----------
    frames : list of ndarray, shape (T_k + 1, frame_size)
        Observation frames (scaled units, float64) at the reset and after every step, each
        followed by the grasp-onset entries when the env has them (``onset_obs``).
    poses : list of ndarray, shape (T_k + 1, 3)
        True object pose (x, y, theta; m, m, rad) of the same instants.
    frame_size : int
        Entries of one recorded frame (the onset entries included).
    sensing : dict
        The sensing of the frames, as the env was built: ``sensor_model``, ``obs_mode``,
        ``obs_noise`` (scaled units) and ``rand_sensors`` (per-episode torque-sensor gains).
    """

    frames: list[np.ndarray]
    poses: list[np.ndarray]
    frame_size: int
    sensing: dict[str, Any] = field(default_factory=dict)
    #: True normal deformations d_n1, d_n2 (m) of the same instants, (T_k + 1, 2) each.
    compressions: list[np.ndarray] = field(default_factory=list)


def collect(env_id: str, env_kwargs: dict[str, Any] | None = None, episodes: int = 40,
            policy: str = "scripted", seed: int = 0, max_steps: int | None = None) -> Episodes:
    """Roll out ``episodes`` episodes (``reset(seed=seed + k)``) of ``policy`` in
    ``gym.make(env_id, history_len=1, **env_kwargs)`` (the scripted policy also sets absolute
    set-point actions); episodes end at a termination, the time limit or ``max_steps``."""
    import gymnasium as gym

    import softhand_env  # noqa: F401  (registers the ids)
    from softhand_env.envs import ENV_IDS

    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES} (got {policy!r})")
    if env_id not in ENV_IDS:
        raise ValueError(f"{env_id!r} is not a soft-hand id (ids: {', '.join(ENV_IDS)})")
    kw = {**(env_kwargs or {}), "history_len": 1}
    if policy == "scripted":
        kw.update(action_mode="absolute", normalize_action=False)
    env = gym.make(env_id, **kw)
    layout = env.unwrapped.config.layout  # type: ignore[attr-defined]
    # the newest frame, then the grasp-onset entries (if any) that follow the frames
    cols = np.r_[0:layout.frame_size, layout.history_size:layout.blind_size]
    sensing = sensing_of(env.unwrapped)
    dt = float(env.unwrapped.dt)  # type: ignore[attr-defined]
    frames, poses, compressions = [], [], []
    for k in range(episodes):
        obs, info = env.reset(seed=seed + k)
        rng = np.random.default_rng([seed, k])
        env.action_space.seed(int(rng.integers(2**31)))
        walk = SetpointWalk(info["setpoint"], dt, rng)
        fr, po = [np.asarray(obs[cols], dtype=np.float64)], [np.asarray(info["object_pose"])]
        dn = [np.asarray(info["deformation"][:2])]
        t = 0
        while max_steps is None or t < max_steps:
            action = walk() if policy == "scripted" else env.action_space.sample()
            obs, _, terminated, truncated, info = env.step(action)
            t += 1
            fr.append(np.asarray(obs[cols], dtype=np.float64))
            po.append(np.asarray(info["object_pose"]))
            dn.append(np.asarray(info["deformation"][:2]))
            if terminated or truncated:
                break
        frames.append(np.array(fr))
        poses.append(np.array(po))
        compressions.append(np.array(dn))
    env.close()
    return Episodes(frames, poses, len(cols), sensing, compressions)


def sensing_of(env: Any) -> dict[str, Any]:
    """The sensing of a soft-hand env (``env.unwrapped``): ``sensor_model``, ``obs_mode``,
    ``obs_noise`` (the standard deviation in scaled units the env adds, the preset resolved)
    and ``rand_sensors``."""
    cfg, options = env.config, env.options
    return {"sensor_model": options.sensor_model, "obs_mode": options.obs_mode,
            "obs_noise": float(cfg.randomization.obs_noise),
            "rand_sensors": bool(cfg.rand_sensors)}


def sensing_text(sensing: dict[str, Any]) -> str:
    """``"sensor_model realistic, obs_mode proprio, obs_noise 0.01, rand_sensors"``: the
    sensing of :func:`sensing_of` as the table's title shows it."""
    text = (f"sensor_model {sensing['sensor_model']}, obs_mode {sensing['obs_mode']}, "
            f"obs_noise {sensing['obs_noise']:g}")
    return text + (", rand_sensors" if sensing.get("rand_sensors") else "")


def stack_frames(frames: np.ndarray, k: int) -> np.ndarray:
    """Rows t = [frame_t, frame_{t-1}, ..., frame_{t-k+1}] of one episode (frames (T, F));
    frame 0 stands in before the start. Returns (T, k * F)."""
    T = len(frames)
    idx = np.maximum(np.arange(T)[:, None] - np.arange(k)[None, :], 0)
    return frames[idx].reshape(T, -1)


def split_episodes(n: int, held_out: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the training and held-out episodes (a seeded permutation; at least one
    episode on each side)."""
    if n < 2:
        raise ValueError(f"need at least 2 episodes to hold some out (got {n})")
    perm = np.random.default_rng(seed).permutation(n)
    n_test = min(n - 1, max(1, round(held_out * n)))
    return np.sort(perm[n_test:]), np.sort(perm[:n_test])


def _torch() -> Any:
    try:
        import torch
    except ImportError:
        raise CliError("softhand_env.tools.observability needs PyTorch "
                       "(pip install 'softhand-env[train]')") from None
    return torch


def fit_mlp(X: np.ndarray, Y: np.ndarray, hidden: Sequence[int] = (128, 128),
            epochs: int = 150, batch: int = 256, lr: float = 1e-3, seed: int = 0) -> Any:
    """Fit an MLP (ReLU, Adam, mean-squared error on standardised inputs and targets).

    Parameters
    ----------
    X : ndarray, shape (n, d)
    Y : ndarray, shape (n, m)
    hidden : widths of the hidden layers

    Returns
    -------
    callable
        ``predict(X) -> Y`` (ndarray (n', m), Y's units).
    """
    torch = _torch()
    torch.manual_seed(seed)
    torch.set_num_threads(1)
    x_mu, x_sd = X.mean(0), X.std(0) + 1e-8
    y_mu, y_sd = Y.mean(0), Y.std(0) + 1e-12
    layers: list[Any] = []
    width = X.shape[1]
    for h in hidden:
        layers += [torch.nn.Linear(width, h), torch.nn.ReLU()]
        width = h
    layers.append(torch.nn.Linear(width, Y.shape[1]))
    net = torch.nn.Sequential(*layers).double()
    xt = torch.from_numpy((X - x_mu) / x_sd)
    yt = torch.from_numpy((Y - y_mu) / y_sd)
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=epochs)
    gen = torch.Generator().manual_seed(seed)
    n = len(xt)
    for _ in range(epochs):
        order = torch.randperm(n, generator=gen)
        for i in range(0, n, batch):
            b = order[i : i + batch]
            opt.zero_grad()
            loss = torch.mean((net(xt[b]) - yt[b]) ** 2)
            loss.backward()
            opt.step()
        sched.step()

    def predict(Xn: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            out = net(torch.from_numpy((Xn - x_mu) / x_sd)).numpy()
        return out * y_sd + y_mu

    return predict


@dataclass(frozen=True)
class Row:
    """Held-out accuracy of one regressor.

    Attributes
    ----------
    label : str
        ``"mean"`` or ``"<k> frame(s)"``.
    rmse_x_mm, rmse_y_mm, rmse_theta_deg : float
    within : float
        Fraction of held-out frames with |x error| < 1 mm and |theta error| < 1 deg.
    within_strict : float
        The same within 0.5 mm and 0.5 deg.
    n_frames : int
        Held-out frames.
    """

    label: str
    rmse_x_mm: float
    rmse_y_mm: float
    rmse_theta_deg: float
    within: float
    within_strict: float
    n_frames: int


def score(label: str, pred: np.ndarray, true: np.ndarray) -> Row:
    """:class:`Row` of predicted vs true poses (n, 3) (m, m, rad)."""
    err = pred - true
    rmse = np.sqrt(np.mean(err**2, axis=0))
    ok = (np.abs(err[:, 0]) < X_TOL) & (np.abs(err[:, 2]) < THETA_TOL)
    strict = (np.abs(err[:, 0]) < X_TOL_STRICT) & (np.abs(err[:, 2]) < THETA_TOL_STRICT)
    return Row(label, 1e3 * rmse[0], 1e3 * rmse[1], math.degrees(rmse[2]), float(ok.mean()),
               float(strict.mean()), len(true))


@dataclass(frozen=True)
class CompressionRow:
    """Held-out accuracy of one regressor of the compressions d_n1, d_n2 (``--target
    compression``).

    Attributes
    ----------
    label : str
    rmse_mm : float
        RMSE over both fingers and every held-out frame (mm).
    rmse_deep_mm, bias_deep_mm : float
        RMSE and mean error (mm) over the fingers compressed beyond :data:`DEEP_DN` (NaN if
        none).
    within : float
        Fraction of held-out frames with both fingers within :data:`DN_TOL`.
    n_frames, n_deep : int
        Held-out frames, and finger readings beyond :data:`DEEP_DN`.
    """

    label: str
    rmse_mm: float
    rmse_deep_mm: float
    bias_deep_mm: float
    within: float
    n_frames: int
    n_deep: int


def score_compression(label: str, pred: np.ndarray, true: np.ndarray) -> CompressionRow:
    """:class:`CompressionRow` of predicted vs true compressions (n, 2) (m)."""
    err = pred - true
    deep = true > DEEP_DN
    rmse_deep = 1e3 * math.sqrt(np.mean(err[deep] ** 2)) if deep.any() else math.nan
    bias_deep = 1e3 * float(np.mean(err[deep])) if deep.any() else math.nan
    return CompressionRow(label, 1e3 * math.sqrt(np.mean(err**2)), rmse_deep, bias_deep,
                          float(np.all(np.abs(err) < DN_TOL, axis=1).mean()), len(true),
                          int(deep.sum()))


def observability(data: Episodes, frames: Sequence[int] = (1, 4), held_out: float = 0.25,
                  seed: int = 0, hidden: Sequence[int] = (128, 128), epochs: int = 150,
                  shuffle_labels: bool = False, target: str = "pose"
                  ) -> list[Row] | list[CompressionRow]:
    """Rows of the table: the training-mean baseline, then one MLP per entry of ``frames``
    (stacked frames), trained on the training episodes, scored on the held-out ones; ``target``
    ``"pose"`` (:class:`Row`) or ``"compression"`` (:class:`CompressionRow`)."""
    if target not in TARGETS:
        raise ValueError(f"target must be one of {TARGETS} (got {target!r})")
    train, test = split_episodes(len(data.frames), held_out, seed)
    labels = data.poses if target == "pose" else data.compressions
    scorer: Any = score if target == "pose" else score_compression

    def design(k: int, eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        X = np.vstack([stack_frames(data.frames[e], k) for e in eps])
        Y = np.vstack([labels[e] for e in eps])
        return X, Y

    _, y_test = design(1, test)
    _, y_train = design(1, train)
    rows = [scorer("mean", np.broadcast_to(y_train.mean(0), y_test.shape), y_test)]
    for k in frames:
        X, Y = design(int(k), train)
        if shuffle_labels:
            Y = Y[np.random.default_rng(seed).permutation(len(Y))]
        predict = fit_mlp(X, Y, hidden, epochs, seed=seed)
        Xt, Yt = design(int(k), test)
        rows.append(scorer(f"{k} frame{'s' if k > 1 else ''}", predict(Xt), Yt))
    return rows


def format_table(title: str, rows: Sequence[Row] | Sequence[CompressionRow]) -> str:
    """Markdown table of :func:`observability`'s rows under a ``title`` line."""
    if any(isinstance(r, CompressionRow) for r in rows):
        return _format_compression(title, [r for r in rows if isinstance(r, CompressionRow)])
    lines = [title, "",
             "| input | RMSE x (mm) | RMSE y (mm) | RMSE theta (deg) | within 1 mm and 1 deg "
             "| within 0.5 mm and 0.5 deg |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        assert isinstance(r, Row)
        lines.append(f"| {r.label} | {r.rmse_x_mm:.3f} | {r.rmse_y_mm:.3f} | "
                     f"{r.rmse_theta_deg:.3f} | {100 * r.within:.1f} % | "
                     f"{100 * r.within_strict:.1f} % |")
    return "\n".join(lines)


def _format_compression(title: str, rows: Sequence[CompressionRow]) -> str:
    deep = f"beyond {1e3 * DEEP_DN:g} mm"
    lines = [title, "",
             f"| input | RMSE d_n (mm) | RMSE {deep} (mm) | mean error {deep} (mm) | "
             f"both within {1e3 * DN_TOL:g} mm |",
             "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.label} | {r.rmse_mm:.3f} | {r.rmse_deep_mm:.3f} | "
                     f"{r.bias_deep_mm:+.3f} | {100 * r.within:.1f} % |")
    return "\n".join(lines)


def env_kwargs(items: Sequence[str] | None, sensor_model: str | None = None,
               obs_mode: str | None = None) -> dict[str, Any]:
    """The ``gym.make`` keywords of the command line: the ``--env-kwargs`` items (YAML values,
    :func:`softhand_env.cli.parse_kv`) with ``--sensor-model`` and ``--obs-mode`` (None: the
    id's); ``--sensor-model ideal`` also sets ``rand_sensors=False`` (ideal read-outs have no
    gains to draw; the ``Random`` ``-v1`` ids draw them) unless ``--env-kwargs`` sets it.
    :class:`~softhand_env.cli.CliError` for a keyword given both ways."""
    kwargs = parse_kv(items, "--env-kwargs")
    for key, value in (("sensor_model", sensor_model), ("obs_mode", obs_mode)):
        if value is None:
            continue
        if key in kwargs:
            raise CliError(f"{key} is given twice (--{key.replace('_', '-')} and --env-kwargs "
                           f"{key}:...); give it once")
        kwargs[key] = value
    if sensor_model == "ideal":  # no sensor gains to draw (the Random -v1 ids draw them)
        kwargs.setdefault("rand_sensors", False)
    return kwargs


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; prints the table."""
    ap = ArgumentParser(prog="python -m softhand_env.tools.observability",
                        description=__doc__.splitlines()[0])
    ap.add_argument("--env", required=True, help="registered id, e.g. SoftHandPose-v0")
    ap.add_argument("--sensor-model", choices=SENSOR_MODELS, default=None,
                    help="sensing of the frames (default: the id's; ideal on -v0, realistic "
                         "on -v1)")
    ap.add_argument("--obs-mode", choices=OBS_MODES, default=None,
                    help="observation mode (default: the id's, proprio); proprio_tactile adds "
                         "the fingertip deformations")
    ap.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY:VALUE",
                    help="other gym.make keywords, values as YAML (obs_noise:0.003)")
    ap.add_argument("--frames", type=int, nargs="+", default=[1, 4],
                    help="stacked frames of each regressor (default 1 4)")
    ap.add_argument("--episodes", type=int, default=40, help="episodes (default 40)")
    ap.add_argument("--policy", choices=POLICIES, default="scripted")
    ap.add_argument("--max-steps", type=int, default=None, help="cap on steps per episode")
    ap.add_argument("--held-out", type=float, default=0.25,
                    help="fraction of the episodes held out (default 0.25)")
    ap.add_argument("--hidden", type=int, nargs="+", default=[128, 128],
                    help="hidden layer widths (default 128 128)")
    ap.add_argument("--epochs", type=int, default=150, help="training epochs (default 150)")
    ap.add_argument("--seed", type=int, default=0, help="episode k: reset(seed=SEED + k)")
    ap.add_argument("--shuffle-labels", action="store_true",
                    help="permute the training labels (sanity check: no information)")
    ap.add_argument("--target", choices=TARGETS, default="pose",
                    help="what is regressed: the object's pose (default) or the fingertips' "
                         "normal deformations d_n1, d_n2")
    args = ap.parse_args(argv)
    if args.episodes < 2 or not 0 < args.held_out < 1 or args.epochs < 1:
        ap.error("--episodes must be >= 2, --held-out in (0, 1), --epochs >= 1")
    if min(args.frames) < 1 or min(args.hidden) < 1:
        ap.error("--frames and --hidden must be >= 1")
    if args.max_steps is not None and args.max_steps < 1:
        ap.error("--max-steps must be >= 1")
    if args.seed < 0:
        ap.error("--seed must be >= 0")
    kwargs = env_kwargs(args.env_kwargs, args.sensor_model, args.obs_mode)
    _torch()
    try:
        data = collect(args.env, kwargs, args.episodes, args.policy, args.seed, args.max_steps)
    except (TypeError, ValueError, gym_error()) as exc:
        raise CliError(f"cannot roll out {args.env} {kwargs}: {one_line(exc)}") from None
    rows = observability(data, args.frames, args.held_out, args.seed, args.hidden, args.epochs,
                         args.shuffle_labels, args.target)
    n = sum(len(p) for p in data.poses)
    shown = " ".join(f"{k}:{v}" for k, v in kwargs.items()) or "the id's keywords"
    title = (f"{args.env} ({shown}; {sensing_text(data.sensing)}), {args.policy} policy, "
             f"{args.episodes} episodes "
             f"({n} frames), {rows[0].n_frames} held-out frames"
             + (", target d_n1, d_n2" if args.target == "compression" else "")
             + (", training labels shuffled" if args.shuffle_labels else ""))
    print(format_table(title, rows))
    return 0


def gym_error() -> type[Exception]:
    """Gymnasium's base error (an unknown id, a missing dependency)."""
    import gymnasium.error

    return gymnasium.error.Error


if __name__ == "__main__":
    raise SystemExit(run_cli(main))
