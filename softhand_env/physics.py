"""Physics of the soft hand: owns the state, advances it, exposes named read-outs.

:class:`HandPhysics` is the dm_control-style Physics object the environments use: it holds the
20-element state of :mod:`softhand_env.model`, advances it with the compiled kernel
(:func:`softhand_env.kernel.advance`) under constant finger-angle set-points, and reports
divergence either by raising :class:`PhysicsError` (``strict=True``) or through
:attr:`StepStatus.flags`. Every read-out returns a copy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from softhand_env import friction, kernel
from softhand_env.model import (
    DN_1,
    DT_1,
    N_DIAG,
    NQ,
    NY,
    TH_1,
    X_OBJ,
    csm_rhs,
    initial_state,
    pack_params,
)
from softhand_env.params import HandParams

# the a-priori RK4 stability check lives in softhand_env.stability; these names stay importable
# from here
from softhand_env.stability import (  # noqa: F401
    RK4_REAL_STABILITY,
    check_rk4_stability,
    rk4_stability_margins,
    warn_if_unstable,
)


class PhysicsError(RuntimeError):
    """The simulated state left the model's validity (NaN or constraint blow-up)."""

    def __init__(self, message: str, flags: int):
        super().__init__(message)
        self.flags = flags


FLAG_NAMES = {
    kernel.FLAG_NONFINITE: "nonfinite_state",
    kernel.FLAG_CONSTRAINT: "constraint_violation",
    kernel.FLAG_LOST: "grasp_lost",
    kernel.FLAG_OVERCOMPRESSED: "overcompressed",
    kernel.FLAG_BASE: "contact_past_base",
}


def describe_flags(flags: int) -> list[str]:
    """Names of the status flags set in ``flags`` (see :mod:`softhand_env.kernel`)."""
    return [name for bit, name in FLAG_NAMES.items() if flags & bit]


@dataclass(frozen=True)
class StepStatus:
    """Outcome of :meth:`HandPhysics.step`.

    Attributes
    ----------
    flags : int
        Bitwise OR of the kernel status flags (0 = valid).
    substeps : int
        RK4 substeps taken (fewer than requested only if a fatal flag stopped integration).
    max_ch : float
        Largest |C^H| (m) over the visited states.
    max_cn : float
        Largest |C^N| (m/s) over the visited states.
    impulse : ndarray, shape (4,), or None
        Contact impulses over the substeps taken (N s): normal J_n1, J_n2 (integral of the
        holonomic multipliers; > 0 pushes the fingertip into the object), tangential J_t1,
        J_t2 (integral of the rolling multipliers), see :mod:`softhand_env.friction`.
    """

    flags: int
    substeps: int
    max_ch: float
    max_cn: float
    impulse: np.ndarray | None = field(default=None, compare=False, hash=False)

    @property
    def fatal(self) -> bool:
        """True if the state left the model (NaN, blow-up, lost grasp, over-compression)."""
        return bool(self.flags & kernel.FATAL_FLAGS)

    @property
    def reasons(self) -> list[str]:
        """Names of the flags set."""
        return describe_flags(self.flags)

    @property
    def friction_ratio(self) -> np.ndarray:
        """|J_t| / J_n per finger over the step, shape (2,) (inf where J_n <= 0)."""
        return friction.friction_ratio(self._impulse())

    @property
    def tension(self) -> np.ndarray:
        """True per finger whose normal impulse over the step is negative, shape (2,)."""
        return friction.tension(self._impulse())

    def _impulse(self) -> np.ndarray:
        if self.impulse is None:
            raise ValueError("this StepStatus carries no contact impulses")
        return self.impulse


class HandPhysics:
    """State, integration and read-outs of the chapter-5 model for one hand.

    Parameters
    ----------
    params : HandParams
        Physical and numerical parameters (SI).
    ch_limit : float
        |C^H| (m) above which the state counts as diverged (default 1e-3 m).
    """

    def __init__(self, params: HandParams | None = None, ch_limit: float = kernel.CH_LIMIT):
        self.params = params if params is not None else HandParams()
        warn_if_unstable(self.params, stacklevel=2)
        self.ch_limit = float(ch_limit)
        self._prm = pack_params(self.params)
        self._y = initial_state(self.params)
        self._setpoint = self._y[TH_1 : TH_1 + 2].copy()
        self._time = 0.0
        self._diag = np.zeros(kernel.N_STEP_DIAG)

    # ----------------------------------------------------------------- state management
    @property
    def dt(self) -> float:
        """RK4 substep (s)."""
        return self.params.dt

    @property
    def time(self) -> float:
        """Simulated time since the last reset (s)."""
        return self._time

    @property
    def packed_params(self) -> np.ndarray:
        """Copy of the packed parameter vector, shape (N_PARAMS,)."""
        return self._prm.copy()

    def reset(self, state: np.ndarray | None = None) -> None:
        """Reset to ``state`` (20,) or to the paper's initial point-contact state.

        The set-points become the state's finger angles (nothing commanded yet).
        """
        self.set_state(initial_state(self.params) if state is None else state)
        self._setpoint = self._y[TH_1 : TH_1 + 2].copy()
        self._time = 0.0

    def set_params(self, params: HandParams) -> None:
        """Change the parameters (e.g. domain randomisation); the state is kept."""
        warn_if_unstable(params, stacklevel=2)
        self.params = params
        self._prm = pack_params(params)

    def get_state(self) -> np.ndarray:
        """Copy of the state [q (9), p (9), z (2)], shape (20,)."""
        return self._y.copy()

    def set_state(self, state: np.ndarray) -> None:
        """Set the full state (20,); raises ValueError on wrong shape or non-finite values."""
        state = np.asarray(state, dtype=np.float64)
        if state.shape != (NY,):
            raise ValueError(f"state must have shape ({NY},) (got {state.shape})")
        if not np.all(np.isfinite(state)):
            raise ValueError("state must be finite")
        self._y = state.copy()

    @property
    def setpoint(self) -> np.ndarray:
        """Finger-angle set-points (rad) of the last step, shape (2,)."""
        return self._setpoint.copy()

    # ------------------------------------------------------------------------- stepping
    def step(self, setpoint: np.ndarray, n_substeps: int, strict: bool = True) -> StepStatus:
        """Advance ``n_substeps`` RK4 substeps holding the PID set-points ``setpoint``.

        Parameters
        ----------
        setpoint : array_like, shape (2,)
            Desired finger angles (theta_1^d, theta_2^d) in rad.
        n_substeps : int
            Number of substeps of :attr:`dt` seconds.
        strict : bool
            If True, raise :class:`PhysicsError` when the state diverges (NaN or
            |C^H| > ch_limit); lost grasp and over-compression are reported in the status.

        Raises
        ------
        ValueError
            Non-finite set-points or a non-positive substep count.
        PhysicsError
            On divergence with ``strict=True``.
        """
        u = np.asarray(setpoint, dtype=np.float64).reshape(-1)
        if u.shape != (2,):
            raise ValueError(f"setpoint must have shape (2,) (got {np.shape(setpoint)})")
        if not np.all(np.isfinite(u)):
            raise ValueError(f"setpoint must be finite (got {u.tolist()})")
        n = int(n_substeps)
        if n < 1:
            raise ValueError(f"n_substeps must be >= 1 (got {n_substeps!r})")
        flags, done = kernel.advance(self._y, u, self._prm, n, self.ch_limit, self._diag)
        self._setpoint = u.copy()
        self._time += done * self.params.dt
        status = StepStatus(
            int(flags), int(done), float(self._diag[0]), float(self._diag[1]),
            self._diag[2:6].copy(),
        )
        if strict and flags & (kernel.FLAG_NONFINITE | kernel.FLAG_CONSTRAINT):
            raise PhysicsError(
                f"simulation diverged at t = {self._time:.4f} s: {', '.join(status.reasons)}",
                int(flags),
            )
        return status

    # ------------------------------------------------------------------------ read-outs
    @property
    def object_pose(self) -> np.ndarray:
        """Object (x, y, theta) in m, m, rad, shape (3,)."""
        return self._y[X_OBJ : X_OBJ + 3].copy()

    @property
    def object_velocity(self) -> np.ndarray:
        """Object (dx/dt, dy/dt, dtheta/dt) in m/s, m/s, rad/s, shape (3,)."""
        return self._y[NQ + X_OBJ : NQ + X_OBJ + 3].copy()

    @property
    def finger_angles(self) -> np.ndarray:
        """Joint angles (theta_1, theta_2) in rad, shape (2,)."""
        return self._y[TH_1 : TH_1 + 2].copy()

    @property
    def finger_velocities(self) -> np.ndarray:
        """Joint velocities in rad/s, shape (2,)."""
        return self._y[NQ + TH_1 : NQ + TH_1 + 2].copy()

    @property
    def deformation(self) -> np.ndarray:
        """Fingertip deformations (d_n1, d_n2, d_t1, d_t2) in m, shape (4,)."""
        return self._y[DN_1 : DT_1 + 2].copy()

    def diagnostics(self, setpoint: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Constraint residuals, PID torques and constraint forces at the current state.

        Returns a dict with ``C_H`` (m, (2,)), ``C_N`` (m/s, (2,)), ``torque`` (N m, (2,)) for
        ``setpoint`` (default: the last one) and ``lambda`` (N, (4,): normal 1, 2, tangential
        1, 2).
        """
        u = self._setpoint if setpoint is None else np.asarray(setpoint, dtype=np.float64)
        dy = np.empty(NY)
        diag = np.empty(N_DIAG)
        csm_rhs(self._y, u, self._prm, dy, diag)
        return {
            "C_H": diag[0:2].copy(),
            "C_N": diag[2:4].copy(),
            "torque": diag[4:6].copy(),
            "lambda": diag[6:10].copy(),
        }

    def pid_torques(self, setpoint: np.ndarray | None = None) -> np.ndarray:
        """PID joint torques (N m) of Eq 5.42 at the current state, shape (2,)."""
        return self.diagnostics(setpoint)["torque"]
