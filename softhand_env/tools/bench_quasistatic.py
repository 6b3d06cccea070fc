"""Benchmark: wall time of the Sec. 4.3 handling process for the paper's five grasp angles.

Run ``python -m softhand_env.tools.bench_quasistatic [--repeat N] [--step-deg 0.1]``. The first call
compiles (or loads from numba's on-disk cache) the Newton kernel; that time is printed
separately and excluded from the timed runs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

from softhand_env.cli import ArgumentParser, run_cli
from softhand_env.physics.params import load_hand_params
from softhand_env.quasistatic import PAPER_GRASP_ANGLES, handling_process, linear_path, solve_path


def bench(repeat: int = 3, step_deg: float = 0.1) -> dict[str, float]:
    """Time the five-angle handling process; returns seconds (compile, best, mean) and rows."""
    params = load_hand_params("paper_ch4")
    t0 = time.perf_counter()
    solve_path(linear_path([0.0, 0.0], [0.01, 0.01]), params)
    compile_s = time.perf_counter() - t0
    times = []
    rows = 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        rows = sum(len(handling_process(g, params, math.radians(step_deg)))
                   for g in PAPER_GRASP_ANGLES)
        times.append(time.perf_counter() - t0)
    return {"compile_s": compile_s, "best_s": min(times), "mean_s": sum(times) / len(times),
            "increments": float(rows)}


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; prints the timings (a wrong argument: one line, exit 2)."""
    return int(run_cli(_run, argv))


def _run(argv: Sequence[str] | None) -> int:
    ap = ArgumentParser(prog="python -m softhand_env.tools.bench_quasistatic",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed repetitions (default 3)")
    ap.add_argument("--step-deg", type=float, default=0.1, help="increment in deg (default 0.1)")
    args = ap.parse_args(argv)
    if not 1 <= args.repeat <= 1000 or not 0 < args.step_deg <= 1:
        ap.error("--repeat must be in [1, 1000] and --step-deg in (0, 1]")
    r = bench(args.repeat, args.step_deg)
    print(f"kernel compile / cache load: {r['compile_s']:.2f} s")
    print(f"handling process, 5 grasp angles, {int(r['increments'])} increments at "
          f"{args.step_deg:g} deg: best {r['best_s']:.3f} s, mean {r['mean_s']:.3f} s "
          f"over {args.repeat} run(s) ({r['best_s'] / r['increments'] * 1e6:.1f} us/increment)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
