"""Throughput of the soft-hand environments: ``python -m softhand_env.tools.bench_env``.

Prints environment steps per second (control steps of ``control_dt``, default 20 ms = 200 RK4
substeps) with random actions for

* the single environment (``gym.make``, with its wrappers; reset on episode end),
* ``gym.make_vec`` with ``vectorization_mode="sync"`` and ``"async"`` (one process per env;
  N above ``--async-max``, default 64, is skipped: 512 worker processes are not sensible),
* the native vector environment (``vectorization_mode="vector_entry_point"``, numba threads),

at N = 8, 64, 512 by default. ``--episode-steps K`` instead measures the single environment
with episodes of K steps (resets included) with and without the post-grasp cache
(:func:`softhand_env.envs.start.grasp_cache`), the cost of a reset. Best of ``--repeats``
timed runs (the figures are noisy on a shared machine). A kernel-only line gives the
ceiling: RK4 substeps per second of
:func:`softhand_env.physics.kernel.advance`. Timing is reported, never asserted.

The integrator comparison (:func:`compare_integrators`, printed first; ``--compare-only``
prints only it, ``--no-compare`` skips it) measures ROS2 at its default step
(``hand_overrides={"integrator": "ros2"}``) against RK4 in the same run and prints one line
``fast/rk4 speed ratio: <float>`` per figure (the median over the pairs, followed by min /
median / max): right-hand-side evaluations per simulated second (counted from the step
schedules of a 20 ms control step), the single environment (``SoftHandPose-v0``, random
actions, resets included), the native vector environment at N = ``--compare-n`` (default
512; at least :data:`VECTOR_STEPS_MIN` vector steps a run), and the Random id
(``SoftHandPoseRandom-v0``: RK4 at its 0.05 ms). The timed figures are paired: both
environments are built, then run in turn (RK4, ROS2, RK4, ...) ``--repeats`` times, and each
ratio divides two runs made back to back, so that the ratios hold on a machine whose speed
drifts (rates are the medians). The anchor rows give simulated seconds per wall second of
``SoftHandPose-v0`` under both integrators (the single-env medians) and of MuJoCo's
Reacher-v5 and Pusher-v5 (:mod:`softhand_env.tools.bench_mujoco`, medians; skipped without
``mujoco``), measured in the same run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

import softhand_env  # noqa: F401  (registers the environments)
from softhand_env.cli import ArgumentParser, CliError, check_int, run_cli


def _best(run: Callable[[], float], repeats: int) -> float:
    """Best (largest) rate of ``repeats`` calls of ``run`` returning a rate."""
    return max(run() for _ in range(repeats))


def bench_kernel(steps: int, repeats: int) -> float:
    """RK4 substeps per second of one system (the physics ceiling)."""
    from softhand_env.physics import kernel
    from softhand_env.physics.model import initial_state, pack_params
    from softhand_env.physics.params import load_hand_params

    params = load_hand_params("paper_ch5")
    y, prm = initial_state(params), pack_params(params)
    u, diag = np.radians([6.0, 6.0]), np.zeros(kernel.N_STEP_DIAG)
    kernel.advance(y, u, prm, 200, kernel.CH_LIMIT, diag)

    def run() -> float:
        t0 = time.perf_counter()
        for _ in range(steps):
            kernel.advance(y, u, prm, 200, kernel.CH_LIMIT, diag)
        return steps * 200 / (time.perf_counter() - t0)

    return _best(run, repeats)


def _single_runner(env_id: str, steps: int, **kwargs) -> tuple[Callable[[], float], Any]:
    """(run, env): ``run()`` times ``steps`` random-action steps of ``gym.make(env_id)``
    (resets included) and returns env steps per second; the step path is compiled first."""
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, 2)).astype(np.float32)
    base: Any = env.unwrapped  # a SoftHandEnv
    if not base.config.actions.normalize:
        raise ValueError("the benchmark uses normalised actions")
    env.step(actions[0])  # warm-up: compiles the step path outside the timed runs

    def run() -> float:
        env.reset(seed=0)
        t0 = time.perf_counter()
        for a in actions:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
        return steps / (time.perf_counter() - t0)

    return run, env


def _vector_runner(env_id: str, mode: str, n: int, steps: int,
                   **kwargs) -> tuple[Callable[[], float], Any]:
    """(run, envs): ``run()`` times ``steps`` random-action steps of ``gym.make_vec`` in
    ``mode`` and returns env steps per second (N x vector steps)."""
    import gymnasium as gym

    envs = gym.make_vec(env_id, num_envs=n, vectorization_mode=mode, **kwargs)
    envs.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, n, 2)).astype(np.float32)
    envs.step(actions[0])  # warm-up (thread pool, worker processes)

    def run() -> float:
        t0 = time.perf_counter()
        for a in actions:
            envs.step(a)
        return steps * n / (time.perf_counter() - t0)

    return run, envs


def bench_single(env_id: str, steps: int, repeats: int, **kwargs) -> float:
    """Env steps per second of ``gym.make(env_id)`` with random actions (best of
    ``repeats``)."""
    run, env = _single_runner(env_id, steps, **kwargs)
    rate = _best(run, repeats)
    env.close()
    return rate


def bench_vector(env_id: str, mode: str, n: int, steps: int, repeats: int, **kwargs) -> float:
    """Env steps per second (N x vector steps) of ``gym.make_vec`` in ``mode`` (best of
    ``repeats``)."""
    run, envs = _vector_runner(env_id, mode, n, steps, **kwargs)
    rate = _best(run, repeats)
    envs.close()
    return rate


class Figure(NamedTuple):
    """One figure of the integrator comparison.

    ``rk4``, ``fast``: medians of the paired runs (rates, larger is faster; for the RHS
    counts the exact counts, smaller is cheaper); ``low``, ``median``, ``high``: minimum,
    median and maximum over the pairs of the fast/rk4 speed ratio (one value for counts).
    """

    rk4: float
    fast: float
    low: float
    median: float
    high: float


def paired_rates(runs: Sequence[Callable[[], float]], repeats: int) -> list[list[float]]:
    """Rates of the ``runs`` in turn (A B A B ...), ``repeats`` rounds: one list per run.
    Pairs of one round ran back to back, so their ratio holds while the machine's speed
    drifts."""
    rates: list[list[float]] = [[] for _ in runs]
    for _ in range(repeats):
        for out, run in zip(rates, runs, strict=True):
            out.append(run())
    return rates


def _figure(rk4_rates: Sequence[float], fast_rates: Sequence[float]) -> Figure:
    ratios = [f / r for r, f in zip(rk4_rates, fast_rates, strict=True)]
    return Figure(float(np.median(rk4_rates)), float(np.median(fast_rates)),
                  min(ratios), float(np.median(ratios)), max(ratios))


#: Environment of the single and vector figures, and the Random id, of the comparison.
COMPARE_ID = "SoftHandPose-v0"
COMPARE_RANDOM_ID = "SoftHandPoseRandom-v0"
FAST = {"integrator": "ros2"}
#: Fewest vector steps of a timed run of the comparison's vector figure: at N = 512 a ROS2 run
#: of about 0.15 s. A stall of the host (a few ms) slows a short run more than the long RK4
#: run paired with it, so short runs bias the ratio low (39 steps, about 30 ms, scattered the
#: pairs over 5.5-8 on the idle machine).
VECTOR_STEPS_MIN = 200


def rhs_per_simulated_second(control_dt: float = 0.02, dt: float = 1e-4,
                             ros2_dt: float = 1e-3) -> tuple[float, float]:
    """Right-hand-side evaluations per simulated second of RK4 at ``dt`` and of ROS2 at
    ``ros2_dt`` in calls of ``control_dt`` seconds (RK4: 4 per substep and one at the end of
    a call; ROS2: :func:`softhand_env.physics.rosenbrock.rhs_evaluations`)."""
    from softhand_env.physics.rosenbrock import rhs_evaluations

    n = round(control_dt / dt)
    return (4 * n + 1) / control_dt, rhs_evaluations(control_dt, ros2_dt) / control_dt


def compare_integrators(steps: int, n_vec: int, repeats: int,
                        show: Callable[[str, Figure], None]) -> dict[str, Figure]:
    """ROS2 against RK4 in one run, paired: each timed figure builds both environments, then
    times them in turn (RK4, ROS2, RK4, ...) ``repeats`` times, so that each ratio compares
    runs made back to back. Calls ``show(name, figure)`` per figure and returns name ->
    :class:`Figure` (the RHS counts are exact: rk4 and fast are the counts, all three
    ratios their quotient)."""
    figures: dict[str, Figure] = {}

    def counted(name: str, rk4: float, fast: float) -> None:
        figures[name] = Figure(rk4, fast, rk4 / fast, rk4 / fast, rk4 / fast)
        show(name, figures[name])

    def timed(name: str, make: Callable[[dict[str, Any] | None], Any]) -> None:
        pairs = [make(kw) for kw in (None, FAST)]
        rates = paired_rates([run for run, _ in pairs], repeats)
        for _, env in pairs:
            env.close()
        figures[name] = _figure(rates[0], rates[1])
        show(name, figures[name])

    rk4, fast = rhs_per_simulated_second()
    counted("RHS evaluations per simulated s", rk4, fast)
    rk4_r, _ = rhs_per_simulated_second(dt=5e-5)
    counted("RHS evaluations per simulated s (Random ids)", rk4_r, fast)
    timed(f"single env {COMPARE_ID} (env steps/s)",
          lambda kw: _single_runner(COMPARE_ID, steps, hand_overrides=kw))
    vsteps = max(steps // n_vec, VECTOR_STEPS_MIN)
    timed(f"native vector env N={n_vec} (env steps/s)",
          lambda kw: _vector_runner(COMPARE_ID, "vector_entry_point", n_vec, vsteps,
                                    hand_overrides=kw))
    # the Random id's own hand_overrides ({"dt": 5e-5}) for RK4, replaced for ROS2
    timed(f"single env {COMPARE_RANDOM_ID} (env steps/s)",
          lambda kw: _single_runner(COMPARE_RANDOM_ID, steps,
                                    **({} if kw is None else {"hand_overrides": kw})))
    return figures


def _print_comparison(steps: int, n_vec: int, repeats: int, mujoco_steps: int) -> None:
    from softhand_env.tools import bench_mujoco

    print(f"integrators: RK4 (paper, 0.1 ms; Random ids 0.05 ms) vs ROS2 "
          f"(hand_overrides={FAST}, 1 ms then up to 2 ms); {repeats} paired runs, medians; "
          f"ratio min / median / max over the pairs")

    def show(name: str, fig: Figure) -> None:
        print(f"{name:<48}{'rk4':>5}{fig.rk4:>14,.0f}{'fast':>6}{fig.fast:>14,.0f}", flush=True)
        print(f"  fast/rk4 speed ratio: {fig.median:.2f}   (min {fig.low:.2f}, median "
              f"{fig.median:.2f}, max {fig.high:.2f})", flush=True)

    figures = compare_integrators(steps, n_vec, repeats, show)
    # simulated seconds per wall second, single env (the medians above), beside MuJoCo's
    import gymnasium as gym

    probe: Any = gym.make(COMPARE_ID).unwrapped
    dt = float(probe.dt)
    probe.close()
    single = figures[f"single env {COMPARE_ID} (env steps/s)"]
    for label, rate in (("rk4", single.rk4), ("ros2", single.fast)):
        print(f"{COMPARE_ID + ' ' + label:<34}{rate * dt:>10,.0f} simulated s / wall s")
    for env_id, anchor in bench_mujoco.bench_anchors(mujoco_steps, repeats).items():
        if anchor is None:
            print(f"{env_id:<34}{'skipped':>10}   (mujoco is not installed)")
        else:
            print(f"{env_id:<34}{anchor:>10,.0f} simulated s / wall s")


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point; prints the rates (a wrong argument or env id: one line on
    stderr, exit code 2, before any timing)."""
    run_cli(_run, argv)


def _run(argv: Sequence[str] | None) -> None:
    parser = ArgumentParser(prog="python -m softhand_env.tools.bench_env",
                            description=__doc__.split("\n")[0])
    parser.add_argument("--id", default="SoftHandReorient-v0", help="environment id")
    parser.add_argument("--sizes", type=int, nargs="+", default=[8, 64, 512], help="values of N")
    parser.add_argument("--env-steps", type=int, default=4096,
                        help="env steps per timed run (vector: divided by N, at least 4 steps)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs; the best is shown")
    parser.add_argument("--async-max", type=int, default=64,
                        help="largest N for async mode (one worker process per environment)")
    parser.add_argument("--episode-steps", type=int, default=None,
                        help="only the single env, episodes of this many steps, grasp cache "
                             "on and off")
    parser.add_argument("--compare-n", type=int, default=None,
                        help="N of the native vector env in the integrator comparison "
                             "(default: the largest of --sizes, 512)")
    parser.add_argument("--compare-steps", type=int, default=None,
                        help="env steps per timed run of the integrator comparison "
                             "(default: --env-steps, at most 2000)")
    parser.add_argument("--compare-only", action="store_true",
                        help="only the integrator comparison and the MuJoCo anchors")
    parser.add_argument("--no-compare", action="store_true",
                        help="skip the integrator comparison")
    args = parser.parse_args(argv)
    for n in args.sizes:
        check_int("--sizes", n, 1, 65_536)
    check_int("--env-steps", args.env_steps, 1, 10**9)
    check_int("--repeats", args.repeats, 1, 1000)
    check_int("--async-max", args.async_max, 0, 1024)
    if args.episode_steps is not None:
        check_int("--episode-steps", args.episode_steps, 1, 10**7)
    import gymnasium as gym

    if args.id not in gym.registry or not args.id.startswith("SoftHand"):
        raise CliError(f"--id {args.id!r} is not a soft-hand env id")

    import numba

    if not args.no_compare and args.episode_steps is None:
        steps = args.compare_steps or min(args.env_steps, 2000)
        _print_comparison(steps, args.compare_n or max(args.sizes), args.repeats, steps)
        if args.compare_only:
            return

    if args.episode_steps is not None:
        from softhand_env.envs.start import grasp_cache

        print(f"softhand_env {softhand_env.__version__}: {args.id}, random actions, episodes "
              f"of {args.episode_steps} steps (resets included), best of {args.repeats}")
        for enabled in (False, True):
            with grasp_cache(enabled):
                rate = bench_single(args.id, args.env_steps, args.repeats,
                                    max_episode_steps=args.episode_steps)
            label = f"grasp cache {'on' if enabled else 'off'}"
            print(f"{label:<24}{rate:>14,.0f} env steps/s{1e6 / rate:>10.1f} us/step", flush=True)
        return

    print(f"softhand_env {softhand_env.__version__}: {args.id}, random actions, "
          f"best of {args.repeats}; numba threads: {numba.get_num_threads()}")
    rate = bench_kernel(max(args.env_steps // 4, 100), args.repeats)
    print(f"{'kernel (RK4 substeps/s)':<34}{rate:>14,.0f}   ceiling {rate / 200:,.0f} env steps/s")
    print(f"{'mode':<24}{'N':>6}{'env steps/s':>18}{'us/env step':>14}")

    def show(mode: str, n: int, rate: float | None, note: str = "") -> None:
        if rate is None:
            print(f"{mode:<24}{n:>6}{'skipped':>18}   {note}")
        else:
            print(f"{mode:<24}{n:>6}{rate:>18,.0f}{1e6 / rate:>14.1f}", flush=True)

    show("single (gym.make)", 1, bench_single(args.id, args.env_steps, args.repeats))
    for mode in ("sync", "async", "vector_entry_point"):
        for n in args.sizes:
            if mode == "async" and n > args.async_max:
                show(mode, n, None, f"N > --async-max={args.async_max}")
                continue
            steps = max(args.env_steps // n, 4)
            show(mode, n, bench_vector(args.id, mode, n, steps, args.repeats))


if __name__ == "__main__":
    main()
