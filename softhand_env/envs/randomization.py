"""Domain randomisation of the hand parameters and observation noise (all off by default).

Each ``rand_*`` value is a relative half-width r: at every reset the parameter is multiplied by
``1 + r * U(-1, 1)`` drawn from the environment's ``np_random``. Six uniforms are drawn per reset
(in the order of :data:`FIELDS`) whenever any ``rand_*`` is non-zero, so the random stream does
not depend on which ones are. ``obs_noise`` is the standard deviation of zero-mean Gaussian
noise added to each observation frame (in the scaled units of the observation).

``randomize=True`` fills every value left at ``None`` from :data:`PRESET`; its object-width range
(+-3 %) keeps the post-grasp d_n within about 6.5-8 mm, clear of the 10 mm validity limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softhand_env.physics.params import HandParams, is_finite_real

#: rand_* keyword -> HandParams fields it scales (together, by one factor).
FIELDS: dict[str, tuple[str, ...]] = {
    "rand_width": ("W_obj",),
    "rand_mass": ("M_obj",),
    "rand_inertia": ("I_obj",),
    "rand_stiffness": ("E",),
    "rand_damping": ("c_n", "c_t"),
    "rand_gains": ("Kp", "Kd", "Ki"),
}

#: Values used by ``randomize=True`` for keywords left at ``None``.
PRESET: dict[str, float] = {
    "rand_width": 0.03,
    "rand_mass": 0.2,
    "rand_inertia": 0.2,
    "rand_stiffness": 0.1,
    "rand_damping": 0.2,
    "rand_gains": 0.1,
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
            high = 1.0 if key != "obs_noise" else 10.0
            if not (is_finite_real(value) and 0.0 <= value < high):
                raise ValueError(f"{key} must be a number in [0, {high}) (got {value!r})")
            out[key] = float(value)
        return cls(**out)

    @property
    def params_active(self) -> bool:
        """True if any hand parameter is randomised."""
        return any(getattr(self, key) > 0 for key in FIELDS)

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
