"""Invariants of every environment transition, shared by the reliability tests.

:func:`check_transition` is the oracle the fuzzers (``test_fuzz.py``) and the
divergence tests (``test_divergence.py``) apply after every ``step``: finite
observation inside the space, finite reward equal to the sum of its terms, finite info, and a
termination reason that agrees with the state it reports. It recomputes the fingertip-base
criterion from :func:`softhand_env.physics.contact.max_contact_angle` (chapter 2), not from the
env's
own code. The tests in this file show that the oracle does reject wrong transitions.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401  (registers the environments)
from softhand_env.physics import kernel
from softhand_env.physics.contact import max_contact_angle
from softhand_env.physics.failure import REASONS
from softhand_env.physics.model import DN_1, DN_2, TH_1, TH_2, TH_OBJ

REQUIRED_INFO = ("object_pose", "deformation", "constraint_error", "grasped", "is_success")


def base_overshoot(y: np.ndarray, a: float) -> float:
    """Largest |tan theta_p| / tan(theta_p at the fingertip base) of the two fingers (1 = at
    the base; 0 for a finger without a contact circle), from chapter 2's closed form."""
    out = 0.0
    for dn, theta_p in ((y[DN_1], y[TH_1] - y[TH_OBJ]), (y[DN_2], y[TH_2] + y[TH_OBJ])):
        if 0.0 < dn < a:
            out = max(out, abs(math.tan(theta_p)) / math.tan(float(max_contact_angle(dn, a))))
    return out


def _finite_info(info: dict[str, Any], reason: str | None) -> None:
    for key, value in info.items():
        if isinstance(value, (bool, str, np.bool_)) or value is None:
            continue
        arr = np.asarray(value, dtype=np.float64)
        assert not np.isnan(arr).any(), f"NaN in info[{key!r}]"
        if key == "constraint_error" and reason == "nonfinite_state":
            continue  # documented: inf marks a residual that went non-finite with the state
        if key == "friction_ratio":
            # documented: inf exactly where the normal impulse of the step is <= 0
            no_push = np.asarray(info["contact_impulse"])[:2] <= 0.0
            np.testing.assert_array_equal(np.isinf(arr), no_push)
            continue
        assert np.isfinite(arr).all(), f"inf in info[{key!r}]"


def check_transition(
    env: gym.Env, obs: Any, reward: Any, terminated: Any, truncated: Any, info: dict[str, Any]
) -> None:
    """Assert the invariants of one ``step`` result of a single environment (see module doc).

    ``env`` is the environment that produced the result (wrapped or not); its current physics
    state is the state after the step.
    """
    base = env.unwrapped
    cfg = base.config
    assert isinstance(obs, np.ndarray) and obs.dtype == np.float32
    assert obs.shape == base.observation_space.shape
    assert np.isfinite(obs).all(), f"non-finite obs {obs}"
    assert base.observation_space.contains(obs)
    assert isinstance(reward, float) and math.isfinite(reward), reward
    assert isinstance(terminated, bool) and isinstance(truncated, bool)
    for key in REQUIRED_INFO:
        assert key in info, key
    reason = info.get("termination_reason")
    assert (reason is not None) == terminated, (reason, terminated)
    _finite_info(info, reason)
    terms = [info[t] for t in base.task.terms]
    assert reward == sum(terms), f"reward {reward} is not the sum of its terms {terms}"

    # contact: the ratio recomputed from the impulses; slip / tension judged against mu
    imp = np.asarray(info["contact_impulse"])
    jn, jt = imp[:2], imp[2:]
    ratio = np.asarray(info["friction_ratio"])
    with np.errstate(divide="ignore", invalid="ignore"):
        np.testing.assert_array_equal(ratio, np.where(jn > 0.0, np.abs(jt) / jn, np.inf))
    np.testing.assert_array_equal(info["tension"], jn < 0.0)
    mu = base.physics.params.mu
    contact_failed = bool(ratio.max() > mu)  # tension included: its ratio is inf

    y = base.physics.get_state()
    assert np.isfinite(y).all()
    np.testing.assert_array_equal(info["deformation"], y[DN_1 : DN_1 + 4])
    dn = y[[DN_1, DN_2]]
    flags = info["physics_flags"]
    ch = info["constraint_error"][0]
    dn_limit, a = cfg.dn_limit, cfg.params.a
    base_limit = cfg.base_limit
    if not terminated:
        assert flags & kernel.FATAL_FLAGS == 0, flags
        assert ch <= cfg.ch_limit, ch
        assert 0.0 < dn.min() and dn.max() < dn_limit, dn
        assert base_overshoot(y, a) <= base_limit * (1 + 1e-9), base_overshoot(y, a)
        assert info["grasped"]
        assert not (cfg.terminate_on_slip and contact_failed), (ratio, mu)
        if base.task.terms:
            assert info["reward_failure"] == 0.0
        return
    assert reason in REASONS + ("tension", "slip", "success"), reason
    if reason == "success":
        assert info["is_success"] and base.task.terminate_on_success
        return
    if base.task.terms:
        assert info["reward_failure"] == -base.task.failure_weight
    # the reported reason is true of the state, and no higher-priority one applies
    diverged = bool(flags & kernel.FLAG_NONFINITE) or ch > cfg.ch_limit
    assert diverged == (reason in REASONS[:2]), (reason, flags, ch)
    if reason == "nonfinite_state":
        assert flags & kernel.FLAG_NONFINITE
    elif reason == "constraint_violation":
        assert ch > cfg.ch_limit
    over = dn.max() >= dn_limit
    lost = dn.min() <= 0.0
    if not diverged:
        assert (reason == "overcompressed") == over, (reason, dn)
        if not over:
            assert (reason == "grasp_lost") == lost, (reason, dn)
    if reason in ("tension", "slip"):
        assert cfg.terminate_on_slip and contact_failed and not diverged
        assert not over and not lost and not flags & kernel.FATAL_FLAGS
        assert (reason == "tension") == bool(info["tension"].any())
    if reason == "contact_past_base":
        # tolerance: the env evaluates the same closed form in another arrangement
        assert flags & kernel.FLAG_BASE
        assert base_overshoot(y, a) > base_limit * (1 - 1e-9), base_overshoot(y, a)


def rollout_checked(env: gym.Env, actions, seed: int | None = 0) -> list[tuple]:
    """Reset with ``seed``, step ``actions`` checking every transition, reset after an episode
    ends; returns (obs, reward, terminated, truncated, info) per step (reset rows included)."""
    out = []
    obs, info = env.reset(seed=seed)
    out.append((obs, 0.0, False, False, info))
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        check_transition(env, obs, reward, terminated, truncated, info)
        out.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            obs, info = env.reset()
            out.append((obs, 0.0, False, False, info))
    return out


# ------------------------------------------------------------------ the oracle can fail
def _one_step(**kwargs):
    env = gym.make("SoftHandReorient-v0", **kwargs)
    env.reset(seed=0)
    return env, env.step(np.zeros(2, dtype=np.float32))


def test_oracle_accepts_a_normal_step():
    env, result = _one_step()
    check_transition(env, *result)


@pytest.mark.parametrize(
    "tamper, message",
    [
        (lambda r: (r[0] * np.nan, *r[1:]), "obs"),
        (lambda r: (r[0], r[1] + 1.0, *r[2:]), "sum"),
        (lambda r: (*r[:4], {**r[4], "object_pose": np.array([np.nan, 0.0, 0.0])}), "NaN"),
        (lambda r: (*r[:4], {**r[4], "reward_goal": math.inf}), "inf"),
        (lambda r: (r[0], r[1], True, False, {**r[4], "termination_reason": "grasp_lost"}), None),
    ],
)
def test_oracle_rejects_tampered_transitions(tamper, message):
    env, result = _one_step()
    with pytest.raises(AssertionError, match=message):
        check_transition(env, *tamper(result))


def test_base_overshoot_is_one_at_the_fingertip_base():
    a, dn = 0.02, 0.007
    y = np.zeros(20)
    y[DN_1] = y[DN_2] = dn
    y[TH_1] = float(max_contact_angle(dn, a))  # contact angle theta_1 - theta_obj at the base
    assert base_overshoot(y, a) == pytest.approx(1.0, rel=1e-12)
    y[TH_OBJ] = 0.01  # rotating the object towards finger 1 backs its contact off the base
    assert base_overshoot(y, a) < 1.0
