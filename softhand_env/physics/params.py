"""Typed, validated hand parameters and their YAML form.

:class:`HandParams` holds every physical and numerical parameter of the hand in SI units. The
YAML files in ``configs/hand/`` use keys that *name their unit* (``L_mm``, ``E_MPa``,
``I_obj_kg_mm2`` ...); :func:`load_hand_params` converts them to SI, rejects unknown keys and
out-of-range values with a message that names the key, and fills keys a file omits from the
defaults (Table 5.1 of the dissertation).

Key table (YAML key -> field, SI unit):

===================  ==========  ============================================================
YAML key             field       meaning (SI unit of the field)
===================  ==========  ============================================================
``L_mm``             L           finger length (m)
``root_spacing_mm``  W_fi        distance between the finger roots 2 W_fi; the field is W_fi (m)
``a_mm``             a           fingertip radius (m)
``W_obj_mm``         W_obj       object width (m)
``d_fi_mm``          d_fi        half finger thickness (m)
``M_obj_kg``         M_obj       object mass (kg)
``I_obj_kg_mm2``     I_obj       object moment of inertia (kg m^2)
``I_1_kg_mm2``       I_1         right finger moment of inertia (kg m^2)
``I_2_kg_mm2``       I_2         left finger moment of inertia (kg m^2)
``M_deform_kg``      M_deform    inertia of the four deformation coordinates (kg); ``null``
                                 means "equal to M_obj" as printed in Eq 5.14
``E_MPa``            E           Young's modulus of the fingertip (Pa)
``g_m_s2``           g           gravitational acceleration along -y (m/s^2)
``c_n_Ns_m``         c_n         viscosity on d_n1, d_n2 (N s/m)
``c_t_Ns_m``         c_t         viscosity on d_t1, d_t2 (N s/m)
``Kp_Nm_rad``        Kp          PID proportional gain (N m/rad)
``Kd_Nms_rad``       Kd          PID derivative gain (N m s/rad)
``Ki_Nm_rads``       Ki          PID integral gain (N m/(rad s))
``alpha_1_s``        alpha       CSM Baumgarte gain of the holonomic constraints (1/s)
``beta_1_s``         beta        CSM Baumgarte gain of the non-holonomic constraints (1/s)
``dt_ms``            dt          RK4 substep (s); under ``integrator: ros2`` the unit in
                                 which control periods are counted (they stay multiples of it)
``integrator``       integrator  ``"rk4"`` (classic RK4 at ``dt``, default, the paper's
                                 scheme) or ``"ros2"`` (the linearly implicit Rosenbrock
                                 method of :mod:`softhand_env.physics.rosenbrock` at
                                 ``ros2_dt``)
``ros2_dt_ms``       ros2_dt     ROS2 step (s) after each call's start (default 1 ms; the
                                 rest of a call takes steps of up to twice it; used by
                                 ``integrator: ros2``)
``cross_term``       cross_term  sign of the d_n^2 d_t tan(theta_p) term: ``"uniform"`` (-1
                                 for both fingers, default, mirror-symmetric) or
                                 ``"printed"`` ((-1)^i as printed in Eq 5.5)
``bending_scale``    bending     dimensionless factor on the bending term d_n d_t^2 (1 = Eq
                                 5.5; large values hold d_t near zero, as in chapter 4)
``mu``               mu          Coulomb friction coefficient fingertip/object (dimensionless);
                                 the largest friction ratio |J_t| / J_n a contact can hold
                                 (:mod:`softhand_env.physics.friction`); not used by the dynamics
===================  ==========  ============================================================

Table 5.1 prints the PID gains (Kp = 300, Kd = 14, Ki = 0.1) without units; they are taken per
radian of joint angle (N m/rad, N m s/rad, N m/(rad s)), as the YAML keys say. Read per degree
(x 180/pi) the finger mode of the paper's own simulation at dt = 0.1 ms would be far beyond
RK4's stability limit (:mod:`softhand_env.physics.stability`), so the per-radian reading is the one
the paper's run supports.

The friction coefficient is not in the dissertation. The default ``mu = 1.0`` is for its soft
polyurethane-gel fingertips (E = 0.23-0.30 MPa, far softer than any cast urethane grade) on a
dry, smooth rigid object: the dry friction of polyurethane elastomers rises as their hardness
falls and is that of soft rubbers for the soft grades, about 1 and above (Gallagher
Corporation, *Polyurethane Technical Data & Design Guide*, 2016, section "Coefficient of
Friction"; soft rubber on dry smooth surfaces 1-2 in the common engineering tables). It is a
stated assumption, not a measurement: randomise it, or set it to the value measured for
another fingertip/object pair. The paper's motions need at most 0.54 (see the README).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs"

#: Allowed values of :attr:`HandParams.cross_term`.
CROSS_TERMS = ("uniform", "printed")
#: Allowed values of :attr:`HandParams.integrator`.
INTEGRATORS = ("rk4", "ros2")
#: Fields whose value is a name, not a number: field -> allowed values.
_CHOICES: dict[str, tuple[str, ...]] = {"cross_term": CROSS_TERMS, "integrator": INTEGRATORS}


@dataclass(frozen=True)
class HandParams:
    """All parameters of the two-finger soft hand, SI units (defaults: Table 5.1).

    Instances are immutable and validated on construction; use :meth:`replace` to derive a
    variant. ``ValueError`` names the offending field and its allowed range.
    """

    L: float = 0.0762
    W_fi: float = 0.0485
    a: float = 0.020
    W_obj: float = 0.049
    d_fi: float = 0.004
    M_obj: float = 0.3
    I_obj: float = 125e-6
    I_1: float = 125e-6
    I_2: float = 125e-6
    M_deform: float | None = None
    E: float = 0.232e6
    g: float = 9.81
    c_n: float = 300.0
    c_t: float = 300.0
    Kp: float = 300.0
    Kd: float = 14.0
    Ki: float = 0.1
    alpha: float = 20000.0
    beta: float = 10000.0
    dt: float = 1e-4
    cross_term: str = "uniform"
    bending: float = 1.0
    mu: float = 1.0
    integrator: str = "rk4"
    ros2_dt: float = 1e-3

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            _check_field(f.name, getattr(self, f.name))
        self._check_width()

    def __hash__(self) -> int:
        # the fields' hash (as the dataclass would compute it), computed once: parameters
        # are dictionary keys of the grasp-state cache at every episode start
        h = self.__dict__.get("_hash")
        if h is None:
            h = hash(tuple(getattr(self, name) for name in _FIELD_ORDER))
            object.__setattr__(self, "_hash", h)
        return h

    def __getstate__(self) -> dict[str, Any]:
        # without the cached hash: str hashes differ between processes, and replace()'s
        # copy changes fields
        state = self.__dict__.copy()
        state.pop("_hash", None)
        return state

    def _check_width(self) -> None:
        """Refuse an object too wide for the hand (the one check across fields)."""
        if self.W_obj / 2 + self.a > self.W_fi - self.d_fi + self.L * 0.5:
            raise ValueError(
                "W_obj is too wide for the hand: W_obj/2 + a must be below W_fi - d_fi + L/2 "
                f"(got W_obj={self.W_obj!r})"
            )

    @property
    def m_deform(self) -> float:
        """Inertia of each deformation coordinate d_n, d_t (kg); M_obj unless overridden."""
        return self.M_obj if self.M_deform is None else float(self.M_deform)

    @property
    def cross_signs(self) -> tuple[float, float]:
        """Sign of the cross term d_n^2 d_t tan(theta_p) for fingers 1 and 2."""
        return (-1.0, -1.0) if self.cross_term == "uniform" else (-1.0, 1.0)

    def replace(self, **changes: Any) -> HandParams:
        """Return a validated copy with ``changes`` applied (field names, SI units).

        Raises ``ValueError`` for an unknown field or a value out of range (naming the field).
        """
        unknown = sorted(set(changes) - _FIELD_NAMES)
        if unknown:
            fields = ", ".join(f.name for f in dataclasses.fields(self))
            raise ValueError(f"unknown HandParams field(s) {unknown}; fields: {fields}")
        # the same checks as construction, on the changed fields only (the others were
        # checked when this instance was built): a randomised episode start derives two
        # variants, and checking all 23 fields cost about 40 us each
        for name, value in changes.items():
            _check_field(name, value)
        new = object.__new__(HandParams)
        state = new.__dict__  # an immutable instance: its fields are written here only
        state.update(self.__dict__)
        state.pop("_hash", None)
        state.update(changes)
        new._check_width()
        return new

    def to_yaml_dict(self) -> dict[str, Any]:
        """The YAML form (unit-named keys), inverse of :func:`hand_params_from_dict`."""
        out: dict[str, Any] = {}
        for key, (field, scale) in YAML_KEYS.items():
            value = getattr(self, field)
            out[key] = value if (scale is None or value is None) else float(value) / scale
        return out


# field -> (low, high, low bound included)
_RANGES: dict[str, tuple[float, float, bool]] = {
    "L": (0.0, 1.0, False),
    "W_fi": (0.0, 1.0, False),
    "a": (0.0, 0.5, False),
    "W_obj": (0.0, 1.0, False),
    "d_fi": (0.0, 0.5, True),
    "M_obj": (0.0, 100.0, False),
    "I_obj": (0.0, 10.0, False),
    "I_1": (0.0, 10.0, False),
    "I_2": (0.0, 10.0, False),
    "M_deform": (0.0, 100.0, False),
    "E": (0.0, 1e10, False),
    "g": (0.0, 100.0, True),
    "c_n": (0.0, 1e6, True),
    "c_t": (0.0, 1e6, True),
    "Kp": (0.0, 1e6, True),
    "Kd": (0.0, 1e6, True),
    "Ki": (0.0, 1e6, True),
    "alpha": (0.0, 1e7, False),
    "beta": (0.0, 1e7, False),
    "dt": (0.0, 1e-2, False),
    "bending": (0.0, 1e9, False),
    "mu": (0.0, 10.0, False),
    "ros2_dt": (0.0, 1e-2, False),
}

#: YAML key -> (HandParams field, multiply YAML value by this to get SI; None = no unit)
YAML_KEYS: dict[str, tuple[str, float | None]] = {
    "L_mm": ("L", 1e-3),
    "root_spacing_mm": ("W_fi", 0.5e-3),
    "a_mm": ("a", 1e-3),
    "W_obj_mm": ("W_obj", 1e-3),
    "d_fi_mm": ("d_fi", 1e-3),
    "M_obj_kg": ("M_obj", 1.0),
    "I_obj_kg_mm2": ("I_obj", 1e-6),
    "I_1_kg_mm2": ("I_1", 1e-6),
    "I_2_kg_mm2": ("I_2", 1e-6),
    "M_deform_kg": ("M_deform", 1.0),
    "E_MPa": ("E", 1e6),
    "g_m_s2": ("g", 1.0),
    "c_n_Ns_m": ("c_n", 1.0),
    "c_t_Ns_m": ("c_t", 1.0),
    "Kp_Nm_rad": ("Kp", 1.0),
    "Kd_Nms_rad": ("Kd", 1.0),
    "Ki_Nm_rads": ("Ki", 1.0),
    "alpha_1_s": ("alpha", 1.0),
    "beta_1_s": ("beta", 1.0),
    "dt_ms": ("dt", 1e-3),
    "cross_term": ("cross_term", None),
    "bending_scale": ("bending", None),
    "mu": ("mu", None),
    "integrator": ("integrator", None),
    "ros2_dt_ms": ("ros2_dt", 1e-3),
}
_FIELD_TO_KEY = {field: key for key, (field, _) in YAML_KEYS.items()}


_FIELD_ORDER = tuple(f.name for f in dataclasses.fields(HandParams))
_FIELD_NAMES = frozenset(_FIELD_ORDER)


def _check_field(name: str, value: Any) -> None:
    """Raise ``ValueError`` naming field ``name`` if ``value`` is not one of its choices or
    not a real number in its range."""
    if name in _CHOICES:
        allowed = _CHOICES[name]
        if not (isinstance(value, str) and value in allowed):
            raise ValueError(f"{name} must be one of {allowed} (got {value!r})")
        return
    if name == "M_deform" and value is None:
        return
    if type(value) is float:  # the common case, as _in_range judges it, without its calls
        low, high, closed_low = _RANGES[name]
        if (value >= low if closed_low else value > low) and value <= high:
            return
    if not _in_range(name, value):
        raise ValueError(f"{name} must be a real number in {range_text(name)} (got {value!r})")


def is_finite_real(value: Any) -> bool:
    """True for a finite real number (int, float or their NumPy kinds; not a bool).

    An int too large for a float (e.g. a 400-digit YAML integer) is not finite here, so it is
    rejected with a ``ValueError`` instead of overflowing later.
    """
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, (int, np.integer)):
        return bool(abs(int(value)) <= sys.float_info.max)
    return isinstance(value, (float, np.floating)) and math.isfinite(value)


def _in_range(field: str, value: Any, scale: float = 1.0) -> bool:
    """True if ``value * scale`` is a valid value of numeric field ``field`` (no overflow)."""
    if not is_finite_real(value):
        return False
    low, high, closed_low = _RANGES[field]
    low, high = low / scale, high / scale
    return (value >= low if closed_low else value > low) and value <= high


def range_text(field: str, scale: float = 1.0) -> str:
    """Allowed range of numeric field ``field`` as text, in units of ``scale`` SI units."""
    low, high, closed_low = _RANGES[field]
    return f"{'[' if closed_low else '('}{low / scale:g}, {high / scale:g}]"


def hand_params_from_dict(
    data: Mapping[str, Any], base: HandParams | None = None, source: str = "config"
) -> HandParams:
    """Build :class:`HandParams` from a mapping with unit-named YAML keys.

    Parameters
    ----------
    data : mapping
        Keys from the table in the module docstring; values in the unit the key names.
    base : HandParams, optional
        Values for keys ``data`` omits (default: Table 5.1).
    source : str
        Name used in error messages (e.g. the file path).

    Raises
    ------
    ValueError
        Not a mapping, unknown key, non-numeric value or value out of range; the message names
        the key and its allowed range in the key's unit.
    """
    base = base if base is not None else HandParams()
    if not isinstance(data, Mapping):
        raise ValueError(f"{source}: expected a mapping of keys to values (got {data!r})")
    changes: dict[str, Any] = {}
    for key, value in data.items():
        if key not in YAML_KEYS:
            raise ValueError(
                f"{source}: unknown key {key!r}; allowed keys: {', '.join(sorted(YAML_KEYS))}"
            )
        field, scale = YAML_KEYS[key]
        if field in _CHOICES or (field == "M_deform" and value is None):
            changes[field] = value
            continue
        unit = 1.0 if scale is None else scale
        if not _in_range(field, value, unit):
            raise ValueError(
                f"{source}: {key} must be a number in {range_text(field, unit)} (got {value!r})"
            )
        changes[field] = float(value) * unit
    try:
        return base.replace(**changes)
    except ValueError as exc:
        # a cross-field check (or rounding at a range end): name the YAML key the user wrote
        msg = str(exc)
        bad_field = msg.split(" ", 1)[0]
        bad_key = _FIELD_TO_KEY.get(bad_field)
        prefix = (
            f"{bad_key}: " if bad_key is not None and bad_key in data and bad_key != bad_field
            else ""
        )
        raise ValueError(f"{source}: {prefix}{msg}") from None


def load_hand_params(name_or_path: str | Path = "paper_ch5", **overrides: Any) -> HandParams:
    """Load hand parameters from a YAML file or a built-in config name.

    Parameters
    ----------
    name_or_path : str or Path
        ``"paper_ch5"`` (Table 5.1), ``"paper_ch4"`` (Table 4.1 with the Table 5.1 root
        spacing), or a path to a YAML file with unit-named keys.
    **overrides
        :class:`HandParams` field values in SI units applied after loading.

    Raises
    ------
    ValueError
        Config not found, not valid YAML, not a mapping, or an invalid key/value (see
        :func:`hand_params_from_dict`); an unknown or out-of-range override (naming the field).
    """
    import yaml

    if not isinstance(name_or_path, (str, Path)):
        raise ValueError(
            f"hand must be a built-in config name or a YAML path (got {name_or_path!r})"
        )
    path = Path(name_or_path)
    if not path.suffix:
        path = CONFIG_DIR / "hand" / f"{name_or_path}.yaml"
    if not path.is_file():
        builtin = sorted(p.stem for p in (CONFIG_DIR / "hand").glob("*.yaml"))
        raise ValueError(f"hand config {str(name_or_path)!r} not found (built-in: {builtin})")
    from softhand_env.physics.safe_yaml import load_bounded, read_bounded

    # bounded: size, no aliases (a 3 KB alias bomb), depth, integer length
    data = load_bounded(read_bounded(path), yaml.SafeLoader, str(path)) or {}
    params = hand_params_from_dict(data, source=str(path))
    return params.replace(**overrides) if overrides else params
