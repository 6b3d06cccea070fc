"""The quasi-static model of chapter 4: :mod:`.solver` (model and Newton-KKT solver) and
:mod:`.handling` (the handling process of Sec. 4.3). Their public names are re-exported here
(``from softhand_env import quasistatic as qs; qs.handling_process(...)``); the model is
described in ``docs/quasistatic.md``.
"""

from softhand_env.quasistatic.handling import (
    PAPER_GRASP_ANGLES,
    PAPER_ROTATION,
    handling_path,
    handling_process,
    handling_summary,
    rotation_angle,
)
from softhand_env.quasistatic.solver import (
    D_DEGENERATE,
    D_OPEN_TOL,
    DEFAULT_STEP,
    SCHEMES,
    QuasiStaticPath,
    QuasiStaticState,
    energy_scalar,
    initial_state,
    linear_path,
    resample,
    resolve_params,
    solve_path,
)

__all__ = [
    "DEFAULT_STEP",
    "D_DEGENERATE",
    "D_OPEN_TOL",
    "PAPER_GRASP_ANGLES",
    "PAPER_ROTATION",
    "SCHEMES",
    "QuasiStaticPath",
    "QuasiStaticState",
    "energy_scalar",
    "handling_path",
    "handling_process",
    "handling_summary",
    "initial_state",
    "linear_path",
    "resample",
    "resolve_params",
    "rotation_angle",
    "solve_path",
]
