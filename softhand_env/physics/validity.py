"""Where the contact model is validated, and a check of states against it.

The fingertip model (Eq 5.5, from the closed forms of chapter 2) rests on compression tests of
the 20 mm-radius polyurethane fingertip with flat rods inclined from 0 to 30 deg, up to a
maximum displacement of 8 mm (Figs 2.8-2.11, 3.4-3.6; the Young's modulus is a linear fit up to
50 % strain). Hence two validated limits per fingertip:

* normal compression ``d_n <= 0.4 a`` (8 mm of a = 20 mm): :data:`VALIDATED_DN_FRACTION`;
* contact angle ``|theta_p| <= 30 deg``: :data:`VALIDATED_THETA_P`.

A third, geometric limit is exact: the closed forms hold while the contact circle stays above
the fingertip base, ``tan|theta_p| <= (a - d_n) / a_c`` (the kernel's ``FLAG_BASE``); at
d_n = a/2 it is 30 deg, at 6 mm 44 deg. Beyond the validated limits the model extrapolates:
the paper's own dynamic example (motions 1-8 of §5.5.1) reaches theta_p = 42.3 deg (motion 7)
and d_n = 7.3 mm (motion 2); the chapter-4 handling process with gravity d_n = 8.6 mm and
theta_p = 43.7 deg (grasp angle 7.2 deg). The environments' hard limits are looser (d_n < a,
or the over-compression ratio of a, and the base limit); :func:`validity_report` tells how far
a state is from the validated box.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
from softhand_env.physics.model import DN_1, TH_1, TH_OBJ
from softhand_env.physics.params import HandParams

#: Largest validated normal compression, as a fraction of the fingertip radius (8 mm / 20 mm).
VALIDATED_DN_FRACTION = 0.4
#: Largest validated contact angle |theta_p| (rad): the compression tests' 30 deg.
VALIDATED_THETA_P = math.radians(30.0)


def contact_state(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normal compressions and contact angles of both fingertips.

    Parameters
    ----------
    y : array_like, shape (..., >= 9)
        States (or generalized coordinates q).

    Returns
    -------
    d_n : ndarray, shape (..., 2)
        Normal compressions d_n1, d_n2 (m).
    theta_p : ndarray, shape (..., 2)
        Contact angles theta_p1 = theta_1 - theta_obj, theta_p2 = theta_2 + theta_obj (rad).
    """
    y = np.asarray(y, dtype=np.float64)
    d_n = y[..., DN_1 : DN_1 + 2]
    theta_p = np.stack(
        [y[..., TH_1] - y[..., TH_OBJ], y[..., TH_1 + 1] + y[..., TH_OBJ]], axis=-1
    )
    return d_n, theta_p


def validated(d_n: np.ndarray, theta_p: np.ndarray, a: float | np.ndarray) -> np.ndarray:
    """True where a fingertip's compression ``d_n`` (m) and contact angle ``theta_p`` (rad),
    both (..., 2), lie inside the validated box, for fingertip radius ``a`` (m; a float or an
    array broadcasting against (..., 1)). Returns bool (..., 2)."""
    return (np.asarray(d_n) <= VALIDATED_DN_FRACTION * np.asarray(a)) & (
        np.abs(theta_p) <= VALIDATED_THETA_P)


@njit(cache=True)
def validated_rows(deformation, finger_angles, object_pose, radius, out):
    """:func:`validated` for N systems from their read-outs, in place (compiled): deformation
    (N, 4) (m), finger angles (N, 2) (rad), object pose (N, 3) (m, m, rad), fingertip radius
    (N,) (m); ``out`` bool (N, 2)."""
    for s in range(deformation.shape[0]):
        th = object_pose[s, 2]
        for f in range(2):
            theta_p = finger_angles[s, f] - th if f == 0 else finger_angles[s, f] + th
            out[s, f] = (deformation[s, f] <= VALIDATED_DN_FRACTION * radius[s]) and (
                abs(theta_p) <= VALIDATED_THETA_P)


def within_validated_range(y: np.ndarray, params: HandParams) -> np.ndarray:
    """True per fingertip whose state lies inside the validated box (module docstring).

    ``y`` as in :func:`contact_state`; returns bool, shape (..., 2).
    """
    d_n, theta_p = contact_state(y)
    return validated(d_n, theta_p, params.a)


def validity_report(y: np.ndarray, params: HandParams) -> dict[str, float | bool]:
    """Largest compression and contact angle over the states ``y`` and their validated limits.

    Parameters
    ----------
    y : array_like, shape (..., >= 9)
        One state or a trajectory of states.
    params : HandParams

    Returns
    -------
    dict
        ``max_d_n`` (m), ``max_theta_p`` (rad, of |theta_p|), ``d_n_limit`` (m),
        ``theta_p_limit`` (rad) and ``within`` (True if every state is inside the box).
    """
    d_n, theta_p = contact_state(y)
    return {
        "max_d_n": float(np.max(d_n)),
        "max_theta_p": float(np.max(np.abs(theta_p))),
        "d_n_limit": VALIDATED_DN_FRACTION * params.a,
        "theta_p_limit": VALIDATED_THETA_P,
        "within": bool(np.all(within_validated_range(y, params))),
    }


__all__ = [
    "VALIDATED_DN_FRACTION",
    "VALIDATED_THETA_P",
    "contact_state",
    "validity_report",
    "within_validated_range",
]
