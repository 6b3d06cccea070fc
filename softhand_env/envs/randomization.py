"""Domain randomisation of the hand parameters and observation noise (all off by default).

Each ``rand_*`` value is a relative half-width r: at every reset the parameter is multiplied by
``1 + r * U(-1, 1)`` drawn from the environment's ``np_random``. Whenever any ``rand_*`` is
non-zero, six uniforms are drawn first (in the order of :data:`FIELDS`, the parameters of the
dynamics) and one more, for the friction coefficient (``rand_friction``), after the goal
(:func:`~softhand_env.envs.start.start_episode`): the random stream does not depend on which
ones are non-zero, and the friction draw leaves the parameters, grasp noise and goal of a
seeded episode as they were before ``rand_friction`` existed. ``obs_noise`` is the standard
deviation of zero-mean Gaussian noise added to each observation frame (in the scaled units of
the observation).

``randomize=True`` fills every value left at ``None`` from :data:`PRESET`; its object-width range
(+-3 %) keeps the post-grasp d_n within about 6.5-8 mm, clear of the 10 mm validity limit.
The environments refuse ranges whose extremes leave RK4's stable region at construction
(:func:`check_ranges`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from softhand_env.envs.options import check_keyword
from softhand_env.physics.params import HandParams, range_text
from softhand_env.physics.stability import check_randomization_ranges

#: rand_* keyword -> HandParams fields it scales (together, by one factor).
FIELDS: dict[str, tuple[str, ...]] = {
    "rand_width": ("W_obj",),
    "rand_mass": ("M_obj",),
    "rand_inertia": ("I_obj",),
    "rand_stiffness": ("E",),
    "rand_damping": ("c_n", "c_t"),
    "rand_gains": ("Kp", "Kd", "Ki"),
}

#: The friction keyword and the HandParams field it scales (drawn after the goal; the
#: friction coefficient does not enter the dynamics).
FRICTION_FIELD = ("rand_friction", "mu")

#: Values used by ``randomize=True`` for keywords left at ``None``.
PRESET: dict[str, float] = {
    "rand_width": 0.03,
    "rand_mass": 0.2,
    "rand_inertia": 0.2,
    "rand_stiffness": 0.1,
    "rand_damping": 0.2,
    "rand_gains": 0.1,
    "rand_friction": 0.2,
    "obs_noise": 0.01,
}


@dataclass(frozen=True)
class Randomization:
    """Resolved randomisation settings (relative half-widths, noise std)."""

    rand_width: float = 0.0
    rand_mass: float = 0.0
    rand_inertia: float = 0.0
    rand_stiffness: float = 0.0
    rand_damping: float = 0.0
    rand_gains: float = 0.0
    rand_friction: float = 0.0
    obs_noise: float = 0.0

    @classmethod
    def resolve(cls, randomize: bool, **values: float | None) -> Randomization:
        """Fill ``None`` values from :data:`PRESET` (``randomize=True``) or with 0; validate."""
        out = {}
        for key, value in values.items():
            if key not in PRESET:
                raise TypeError(f"unknown randomisation keyword {key!r}")
            if value is None:
                value = PRESET[key] if randomize else 0.0
            check_keyword(key, value)
            out[key] = float(value)
        return cls(**out)

    @functools.cached_property
    def params_active(self) -> bool:
        """True if any hand parameter is randomised (the friction coefficient included)."""
        return any(getattr(self, key) > 0 for key in FIELDS) or self.rand_friction > 0

    def sample_params(self, base: HandParams, rng: np.random.Generator) -> HandParams:
        """Draw randomised parameters around ``base`` (returns ``base`` when none is active)."""
        if not self.params_active:
            return base
        factors = 1.0 + rng.uniform(-1.0, 1.0, size=len(FIELDS)) * np.array(
            [getattr(self, key) for key in FIELDS]
        )
        changes = {}
        for factor, fields in zip(factors, FIELDS.values(), strict=True):
            for field in fields:
                changes[field] = float(getattr(base, field) * factor)
        return base.replace(**changes)

    def sample_friction(self, params: HandParams, rng: np.random.Generator) -> HandParams:
        """Draw the friction coefficient around ``params.mu`` (one uniform whenever any hand
        parameter is randomised; returns ``params`` when none is)."""
        if not self.params_active:
            return params
        factor = 1.0 + rng.uniform(-1.0, 1.0) * self.rand_friction
        if factor == 1.0:
            return params
        return params.replace(mu=float(params.mu * factor))

    def check_ranges(self, base: HandParams) -> None:
        """Refuse ranges that leave the model's valid or stable region (``ValueError`` naming
        the keyword and the limit).

        The corners of the box of the dynamics' ``rand_*`` ranges around ``base`` must all
        be stable for RK4 at ``base.dt``
        (:func:`~softhand_env.physics.stability.check_randomization_ranges`), so no draw
        needs a check at reset; ``rand_friction`` must keep mu within its valid range.
        """
        check_randomization_ranges(base, FIELDS, {key: getattr(self, key) for key in FIELDS})
        key, field = FRICTION_FIELD
        top = getattr(base, field) * (1.0 + getattr(self, key))
        try:
            base.replace(**{field: top})
        except ValueError:
            raise ValueError(
                f"{key} = {getattr(self, key):g} draws {field} up to {top:g}, outside its "
                f"valid range {range_text(field)} around {field} = {getattr(base, field):g}"
            ) from None
