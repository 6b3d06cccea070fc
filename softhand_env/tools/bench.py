"""``python -m softhand_env.tools.bench``: speed of the dynamic-model kernels, in one run.

Prints RK4 substeps per second and the real-time factor (simulated seconds per wall second)
for the single-system compiled kernel, the batched kernel at several batch sizes, and the
plain-NumPy reference, all from the same settled grasp state with a set-point step. Each
figure is the best of ``--repeat`` timings (the machine may be shared; best-of-N is the least
noisy estimate of what the code can do). For the batched kernel the last column converts
system-substeps/s into environment steps/s at ``--env-substeps`` (200 = a 20 ms control
period at dt = 0.1 ms): the physics ceiling of the native vector environment.
``--threads`` sets the numba thread count (default: all cores).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence

import numba
import numpy as np

from softhand_env.cli import ArgumentParser, check_int, run_cli
from softhand_env.physics import kernel, model
from softhand_env.physics.params import HandParams
from softhand_env.physics.reference import advance_reference


def best_time(fn: Callable[[], object], repeat: int) -> float:
    """Smallest wall time (s) of ``repeat`` calls of ``fn``."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def grasp_state(params: HandParams) -> np.ndarray:
    y = model.initial_state(params)
    kernel.advance(y, np.radians([6.0, 6.0]), model.pack_params(params), 3000, 1e-3, np.zeros(2))
    return y


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit code (a wrong argument: one line, exit 2)."""
    return int(run_cli(_run, argv))


def _run(argv: Sequence[str] | None) -> int:
    parser = ArgumentParser(prog="python -m softhand_env.tools.bench", description=__doc__)
    parser.add_argument("--substeps", type=int, default=20000, help="substeps per timing")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 8, 64, 512, 1024, 8192])
    parser.add_argument("--env-substeps", type=int, default=200,
                        help="RK4 substeps per environment step (env steps/s column)")
    parser.add_argument("--threads", type=int, default=None, help="numba threads")
    args = parser.parse_args(argv)
    check_int("--substeps", args.substeps, 10, 10**9)
    check_int("--repeat", args.repeat, 1, 1000)
    check_int("--env-substeps", args.env_substeps, 1, 10**6)
    for n in args.batch:
        check_int("--batch", n, 1, 65_536)
    if args.threads is not None:
        check_int("--threads", args.threads, 1,
                  numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
        numba.set_num_threads(args.threads)
    params = HandParams()
    prm = model.pack_params(params)
    y0 = grasp_state(params)
    u = np.radians([20.0, -10.0])
    diag = np.zeros(kernel.N_STEP_DIAG)
    dt = params.dt
    print(f"softhand-env kernel benchmark  (cores: {os.cpu_count()}, numba threads: "
          f"{numba.get_num_threads()}, batch lanes: {kernel.LANES}, RK4 dt = {dt * 1e3:g} ms)")
    print(f"{'kernel':<28}{'N':>6}{'substeps/s':>16}{'system-substeps/s':>20}{'RTF':>10}"
          f"{'env steps/s':>14}")

    def row(name: str, n_sys: int, per_second: float) -> None:
        rtf = per_second * dt
        env = per_second * n_sys / args.env_substeps
        print(f"{name:<28}{n_sys:>6}{per_second:>16,.0f}{per_second * n_sys:>20,.0f}{rtf:>10.1f}"
              f"{env:>14,.0f}")

    n = args.substeps
    kernel.advance(y0.copy(), u, prm, 10, 1e-3, diag)  # compile / load cache

    def single() -> None:
        kernel.advance(y0.copy(), u, prm, n, 1e-3, diag)

    t_single = best_time(single, args.repeat)
    row("single (numba)", 1, n / t_single)

    for N in args.batch:
        Y0 = np.tile(y0, (N, 1))
        U = np.tile(u, (N, 1))
        PRM = np.tile(prm, (N, 1))
        DIAG = np.zeros((N, kernel.N_STEP_DIAG))
        FLAGS = np.zeros(N, dtype=np.int64)
        n_b = max(10, int(n * 64 / max(N, 64)) // 10 * 10)
        kernel.advance_batch(Y0.copy(), U, PRM, 10, 1e-3, DIAG, FLAGS)

        def batched(Y0=Y0, U=U, PRM=PRM, DIAG=DIAG, FLAGS=FLAGS, n_b=n_b) -> None:
            FLAGS[:] = 0
            kernel.advance_batch(Y0.copy(), U, PRM, n_b, 1e-3, DIAG, FLAGS)

        t = best_time(batched, args.repeat)
        row("batched (numba, parallel)", N, n_b / t)

    n_ref = 200
    t_ref = best_time(lambda: advance_reference(y0, u, prm, n_ref), max(1, args.repeat // 2))
    row("NumPy reference (dense KKT)", 1, n_ref / t_ref)
    print(f"single kernel / NumPy reference speed-up: {t_ref / n_ref / (t_single / n):,.0f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
