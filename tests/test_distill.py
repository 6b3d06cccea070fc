"""Teacher-student distillation (agents.distill): a blind student imitates a privileged teacher."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from agents import distill, train
from agents.cli import UserError
from agents.loading import ModelPolicy
from agents.native_vec_env import make_sb3_vec_env

ENV_ID = "SoftHandReorient-v0"
WRAPPER = [{"agents.time_feature.TimeFeature": {"max_steps": 8}}]
KWARGS = {"control_dt": 0.04, "max_episode_steps": 8}
BASE = {"vec_env": "native", "n_envs": 4, "n_steps": 16, "batch_size": 32, "n_epochs": 1,
        "n_timesteps": 64, "policy_kwargs": "dict(net_arch=[16])", "env_wrapper": WRAPPER}


def _conf(path: Path, **entry) -> str:
    path.write_text(yaml.safe_dump({ENV_ID: {**BASE, **entry}}))
    return str(path)


@pytest.fixture(scope="module")
def teacher(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("teacher")
    conf = _conf(d / "teacher.yml", policy="MultiInputPolicy",
                 normalize={"norm_obs": True, "norm_reward": False},
                 env_kwargs={**KWARGS, "privileged_obs": True})
    return train.main(["--env", ENV_ID, "--conf-file", conf, "--log-folder", str(d / "logs"),
                       "--eval-freq", "0", "--save-freq", "0", "--no-progress-bar",
                       "--verbose", "0"])


def _student_args(tmp_path: Path, teacher: Path, **entry) -> list[str]:
    entry = {"policy": "MlpPolicy", "normalize": False, "env_kwargs": dict(KWARGS), **entry}
    conf = _conf(tmp_path / f"student_{len(list(tmp_path.glob('student*.yml')))}.yml", **entry)
    return ["--env", ENV_ID, "--teacher", str(teacher), "--conf-file", conf,
            "--log-folder", str(tmp_path / "logs"), "--iterations", "3", "--rollout-steps", "8",
            "--eval-episodes", "4", "--epochs", "20", "--batch-size", "16"]


def test_student_learns_the_teacher_and_plays_as_a_saved_blind_model(tmp_path, teacher):
    run = distill.main(_student_args(tmp_path, teacher))
    student = ModelPolicy(run)
    record = student.run.record
    assert record["trainer"] == "dagger" and record["teacher"]["path"].endswith(".zip")
    assert "privileged_obs" not in student.env_kwargs  # a plain blind policy at play time
    curve = np.load(run / "dagger_curve.npz")
    assert list(curve["iteration"]) == [0, 1, 2]
    # validation re-seeds its env: the same goals, the same result every time
    from agents.metrics import success_kwargs

    val = make_sb3_vec_env(ENV_ID, 4, 0, {**KWARGS, **success_kwargs(ENV_ID)}, "native",
                           env_wrapper=WRAPPER)
    first = distill.validate(student.model, val, ("theta",), 5000)
    assert distill.validate(student.model, val, ("theta",), 5000) == first
    assert first["success_rate"] == curve["success_rate"][record["best_validation"]["iteration"]]
    np.testing.assert_allclose(curve["beta"], [1.0, 0.5, 0.25])
    # the student reproduces the teacher's actions on states the teacher labels: the fit is
    # far better than the untrained student's (the imitation error the training minimised)
    t = ModelPolicy(teacher)
    venv = make_sb3_vec_env(ENV_ID, 4, 123, {**KWARGS, "privileged_obs": True}, "native",
                            env_wrapper=WRAPPER)
    obs = venv.reset()
    errs, errs0 = [], []
    fresh = train.build(train.resolve_config(train.parse_args(
        ["--env", ENV_ID, "--conf-file", str(tmp_path / "student_0.yml")])), verbose=0)[0]
    for _ in range(8):
        t_act = np.clip(t.model.predict(t.normalize(obs), deterministic=True)[0], -1, 1)
        with torch.no_grad():
            s = distill.student_mean(student.model.policy, torch.as_tensor(obs["observation"]))
            s0 = distill.student_mean(fresh.policy, torch.as_tensor(obs["observation"]))
        errs.append(np.mean((s.numpy() - t_act) ** 2))
        errs0.append(np.mean((s0.numpy() - t_act) ** 2))
        obs = venv.step(t_act)[0]
    assert np.mean(errs) < 0.2 * np.mean(errs0), (np.mean(errs), np.mean(errs0))


def test_teacher_and_student_must_match(tmp_path, teacher, monkeypatch):
    args = _student_args(tmp_path, teacher)
    with pytest.raises(UserError, match="env_kwargs differ"):
        distill.main(args + ["--env-kwargs", "control_dt:0.02"])
    with pytest.raises(UserError, match="normalize: false"):
        distill.main(_student_args(tmp_path, teacher, normalize={"norm_obs": True}))
    with pytest.raises(UserError, match="leave privileged_obs"):
        distill.main(args + ["--env-kwargs", "privileged_obs:true"])
    with pytest.raises(UserError, match="--beta-decay"):
        distill.main(args + ["--beta-decay", "1.5"])
    for flag, value in (("--eval-freq", "100"), ("--n-timesteps", "10"), ("--vec-env", "dummy"),
                        ("--save-freq", "0")):
        with pytest.raises(UserError, match=f"{flag} does not apply"):
            distill.main(args + [flag, value])
    assert not (tmp_path / "logs").exists()  # refusals leave nothing behind
    student = distill.main(args)
    with pytest.raises(UserError, match="privileged_obs: true"):  # a student is no teacher
        distill.main(_student_args(tmp_path, student))
    # a warm start from that student, stopped by its first validation (reported as 100 %)
    real = distill.summarize
    monkeypatch.setattr(distill, "summarize",
                        lambda *a, **k: {**real(*a, **k), "success_rate": 1.0})
    again = distill.main(args + ["--trained-agent", str(student), "--stop-success", "0.9"])
    record = ModelPolicy(again).run.record
    assert record["trained_agent"]["path"] == str(student / f"{ENV_ID}.zip")
    assert list(np.load(again / "dagger_curve.npz")["iteration"]) == [0]
