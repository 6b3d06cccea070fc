"""Teacher-student distillation (agents.distill): a blind student imitates a privileged teacher."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

from agents import distill, train
from agents.common.cli import UserError
from agents.runs.loading import ModelPolicy
from agents.sb3 import imitation
from agents.sb3.native_vec_env import make_sb3_vec_env
from softhand_env.cli import CliError

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
    from agents.common.metrics import success_kwargs

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


def test_fit_threads_apply_to_the_fit_only(tmp_path, teacher, monkeypatch):
    seen: dict[str, set[int]] = {"fit": set(), "predict": set()}
    real_mean, real_validate = distill.student_mean, distill.validate

    def spy_mean(policy, x):
        seen["fit"].add(torch.get_num_threads())
        return real_mean(policy, x)

    def spy_validate(*args, **kwargs):
        seen["predict"].add(torch.get_num_threads())
        return real_validate(*args, **kwargs)

    monkeypatch.setattr(distill, "student_mean", spy_mean)
    monkeypatch.setattr(distill, "validate", spy_validate)
    before = torch.get_num_threads()
    args = _student_args(tmp_path, teacher)
    args[args.index("--iterations") + 1] = "2"
    run = distill.main([*args, "--torch-threads", "1", "--fit-threads", "2"])
    assert seen == {"fit": {2}, "predict": {1}}
    assert ModelPolicy(run).run.record["fit_threads"] == 2
    torch.set_num_threads(before)


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
    with pytest.raises(UserError, match="--lr-final must be in"):
        distill.main(args + ["--lr-final", "0"])
    for flag, value in (("--eval-freq", "100"), ("--n-timesteps", "10"), ("--vec-env", "dummy"),
                        ("--save-freq", "0")):
        with pytest.raises(UserError, match=f"{flag} does not apply"):
            distill.main(args + [flag, value])
    assert not (tmp_path / "logs").exists()  # refusals leave nothing behind
    student = distill.main(args)
    with pytest.raises(UserError, match="privileged_obs: true"):  # a student is no teacher
        distill.main(_student_args(tmp_path, student))
    # a warm start from that student, stopped by its first validation (reported as 100 %)
    real = imitation.summarize
    monkeypatch.setattr(imitation, "summarize",
                        lambda *a, **k: {**real(*a, **k), "success_rate": 1.0})
    again = distill.main(args + ["--trained-agent", str(student), "--stop-success", "0.9"])
    record = ModelPolicy(again).run.record
    assert record["trained_agent"]["path"] == str(student / f"{ENV_ID}.zip")
    assert list(np.load(again / "dagger_curve.npz")["iteration"]) == [0]
    assert record["dagger"]["latency_labels"] is False
    delayed = distill.main(args + ["--latency-labels"])  # no latency here: plain labels
    assert ModelPolicy(delayed).run.record["dagger"]["latency_labels"] is True


def test_student_with_a_longer_history_feeds_the_teacher_its_newest_frames(tmp_path, teacher):
    student_kwargs = {**KWARGS, "history_len": 3}
    run = distill.main(_student_args(tmp_path, teacher, env_kwargs=student_kwargs))
    student = ModelPolicy(run)
    assert student.env_kwargs["history_len"] == 3
    assert student.model.observation_space.shape[0] == 3 * 8 + 1 + 1  # frames, goal, time
    # the teacher's view of a 3-frame observation is exactly the 1-frame observation of the
    # same state: reset both envs with the same seed and step them with the same actions
    long = make_sb3_vec_env(ENV_ID, 2, 7, {**student_kwargs, "privileged_obs": True}, "native",
                            env_wrapper=WRAPPER)
    short = make_sb3_vec_env(ENV_ID, 2, 7, {**KWARGS, "privileged_obs": True}, "native",
                             env_wrapper=WRAPPER)
    o_long, o_short = long.reset(), short.reset()
    for _ in range(3):
        view = distill.teacher_view(o_long, distill.view_layout(KWARGS),
                                    distill.view_layout(student_kwargs))
        for key in o_short:
            np.testing.assert_array_equal(view[key], o_short[key])
        # the older frames are the earlier steps' newest ones (frames are newest first)
        previous = o_long["observation"][:, :8].copy()
        action = np.full((2, 2), 0.3, np.float32)
        o_long, o_short = long.step(action)[0], short.step(action)[0]
        np.testing.assert_array_equal(o_long["observation"][:, 8:16], previous)
    # a teacher with a longer history than the student's cannot be fed
    longer = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER,
                             env_kwargs={**KWARGS, "privileged_obs": True, "history_len": 4})
    hp = {"env_kwargs": student_kwargs, "env_wrapper": WRAPPER, "normalize": False}
    with pytest.raises(UserError, match=r"history_len \(3\) must be at least the teacher's \(4\)"):
        distill.check_pair(longer, ENV_ID, hp)
    assert distill.check_pair(longer, ENV_ID, {**hp, "env_kwargs": {**KWARGS, "history_len": 4}}
                              ) == ({**KWARGS, "history_len": 4}, {"history_len": 4})
    tactile = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER, env_kwargs={
        **KWARGS, "privileged_obs": True, "obs_mode": "proprio_tactile"})
    with pytest.raises(UserError, match="so must the student"):
        distill.check_pair(tactile, ENV_ID, hp)
    other = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER, env_kwargs={
        **KWARGS, "privileged_obs": True, "max_delta_deg": 2.0})
    with pytest.raises(UserError, match="env_kwargs differ"):
        distill.check_pair(other, ENV_ID, hp)
    # a teacher trained on another reward (tighter error scales) plays the same task
    reward = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER, env_kwargs={
        **KWARGS, "privileged_obs": True, "x_scale_mm": 2.0, "theta_scale_deg": 2.0})
    assert distill.check_pair(reward, ENV_ID, hp) == distill.check_pair(
        SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER,
                        env_kwargs={**KWARGS, "privileged_obs": True}), ENV_ID, hp)
    # but not one whose goals or success rule differ
    tolerance = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER, env_kwargs={
        **KWARGS, "privileged_obs": True, "x_tolerance_mm": 2.0})
    with pytest.raises(UserError, match="env_kwargs differ"):
        distill.check_pair(tolerance, ENV_ID, hp)


def test_teacher_labels_a_student_with_its_own_setpoint_ramp():
    """The teacher acts in the student's env: a set-point ramp may differ between them (the
    teacher is checked against its own), any other action keyword may not."""
    hp = {"env_kwargs": {**KWARGS, "setpoint_ramp_ms": 40.0}, "env_wrapper": WRAPPER,
          "normalize": False}
    plain = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER,
                            env_kwargs={**KWARGS, "privileged_obs": True})
    assert distill.check_pair(plain, ENV_ID, hp) == (hp["env_kwargs"], {})
    ramped = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER, env_kwargs={
        **KWARGS, "privileged_obs": True, "setpoint_ramp_ms": 20.0})
    assert distill.check_pair(ramped, ENV_ID, {**hp, "env_kwargs": KWARGS}) == (
        KWARGS, {"setpoint_ramp_ms": 20.0})
    delta = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER, env_kwargs={
        **KWARGS, "privileged_obs": True, "max_delta_deg": 2.0})
    with pytest.raises(UserError, match="env_kwargs differ"):
        distill.check_pair(delta, ENV_ID, hp)


def test_tactile_student_feeds_the_teacher_the_proprio_entries_of_its_frames():
    tactile = {**KWARGS, "obs_mode": "proprio_tactile", "history_len": 2}
    both = [make_sb3_vec_env(ENV_ID, 2, 3, {**kw, "privileged_obs": True}, "native",
                             env_wrapper=WRAPPER) for kw in (tactile, KWARGS)]
    t_layout, s_layout = distill.view_layout(KWARGS), distill.view_layout(tactile)
    assert (s_layout.frame_size, s_layout.history_len) == (12, 2)
    o_tactile, o_plain = both[0].reset(), both[1].reset()
    for _ in range(3):
        view = distill.teacher_view(o_tactile, t_layout, s_layout)
        np.testing.assert_array_equal(view["observation"], o_plain["observation"])
        action = np.full((2, 2), -0.4, np.float32)
        o_tactile, o_plain = both[0].step(action)[0], both[1].step(action)[0]


def test_blind_teacher_and_student_each_read_their_view_of_the_union_observation(tmp_path,
                                                                                 teacher):
    tactile = {**KWARGS, "obs_mode": "proprio_tactile", "history_len": 2}
    joints = {**KWARGS, "history_len": 3}
    blind_teacher = distill.main(_student_args(tmp_path, teacher, env_kwargs=tactile))
    # the union of a 2-frame tactile and a 3-frame joint-only layout: 3 tactile frames
    union = distill.rollout_layout(distill.view_layout(joints), distill.view_layout(tactile),
                                   True)
    assert (union.tactile, union.history_len) == (True, 3)
    own = distill.view_layout(joints)
    assert distill.rollout_layout(own, distill.view_layout(tactile), False) is own
    # each view of the union env's observation is that policy's own env's observation of the
    # same state (same seed, same actions; ideal sensors)
    kws = ({**KWARGS, "obs_mode": "proprio_tactile", "history_len": 3}, tactile, joints)
    envs = [make_sb3_vec_env(ENV_ID, 2, 5, kw, "native", env_wrapper=WRAPPER) for kw in kws]
    obs = [env.reset() for env in envs]
    for _ in range(3):
        for k in (1, 2):
            view = distill.blind_view(obs[0], distill.view_layout(kws[k]), union,
                                      obs[k].shape[-1])
            np.testing.assert_array_equal(view, obs[k])
        action = np.full((2, 2), 0.25, np.float32)
        obs = [env.step(action)[0] for env in envs]
    # the run: a joint-only student of the tactile (blind) teacher
    args = _student_args(tmp_path, blind_teacher, env_kwargs=joints)
    with pytest.raises(UserError, match="needs --blind-teacher"):
        distill.main(args)
    with pytest.raises(UserError, match="must be a blind policy"):
        distill.main(_student_args(tmp_path, teacher, env_kwargs=joints) + ["--blind-teacher"])
    run = distill.main(args + ["--blind-teacher"])
    student = ModelPolicy(run)
    assert student.run.record["dagger"]["blind_teacher"] is True
    assert student.env_kwargs["history_len"] == 3 and "obs_mode" not in student.env_kwargs
    assert student.model.observation_space.shape[0] == 3 * 8 + 1 + 1  # frames, goal, time
    assert list(np.load(run / "dagger_curve.npz")["iteration"]) == [0, 1, 2]


def test_views_keep_or_drop_the_grasp_onset_entries():
    # a joint-only student with the grasp-onset entries, a tactile teacher without them, on
    # randomised object widths (the onset differs per episode); ideal sensors draw nothing
    # for the onset, so each view equals that policy's own env's observation
    base = {**KWARGS, "rand_width": 0.2}
    student = {**base, "history_len": 3, "onset_obs": True}
    tactile = {**base, "obs_mode": "proprio_tactile", "history_len": 2}
    union = distill.rollout_layout(distill.view_layout(student), distill.view_layout(tactile),
                                   True)
    assert (union.tactile, union.history_len, union.onset) == (True, 3, True)
    kws = ({**base, "obs_mode": "proprio_tactile", "history_len": 3, "onset_obs": True},
           tactile, student)
    envs = [make_sb3_vec_env(ENV_ID, 2, 5, kw, "native", env_wrapper=WRAPPER) for kw in kws]
    obs = [env.reset() for env in envs]
    h = union.history_size
    assert np.all(obs[0][:, h:h + 2] != 0)  # a randomised width: the fingers start inclined
    for _ in range(3):
        for k in (1, 2):
            view = distill.blind_view(obs[0], distill.view_layout(kws[k]), union,
                                      obs[k].shape[-1])
            np.testing.assert_array_equal(view, obs[k])
        obs = [env.step(np.full((2, 2), 0.25, np.float32))[0] for env in envs]
    with pytest.raises(ValueError, match="grasp-onset"):
        distill.blind_view(obs[1], distill.view_layout(student), distill.view_layout(tactile))
    # a privileged teacher that reads the onset needs a student that reads it too
    teacher = SimpleNamespace(env_id=ENV_ID, env_wrapper=WRAPPER, env_kwargs={
        **KWARGS, "privileged_obs": True, "onset_obs": True})
    entry = {"env_kwargs": dict(KWARGS), "env_wrapper": WRAPPER}
    with pytest.raises(UserError, match="grasp-onset"):
        distill.check_pair(teacher, ENV_ID, entry)
    distill.check_pair(teacher, ENV_ID, {**entry, "env_kwargs": {**KWARGS, "onset_obs": True}})


def test_step_size_goes_linearly_from_lr_to_lr_final():
    steps = [distill.lr_at(k, 5, 1e-3, 1e-4) for k in range(5)]
    np.testing.assert_allclose(steps, [1e-3, 7.75e-4, 5.5e-4, 3.25e-4, 1e-4])
    assert distill.lr_at(0, 1, 1e-3, 1e-4) == 1e-3  # a single iteration uses --lr
    args = distill.parse_args(["--env", ENV_ID, "--teacher", "t"])
    assert args.dagger.lr_final == args.dagger.lr  # constant by default


def test_minibatches_make_epochs_over_the_data_or_a_fixed_number_of_draws():
    from agents.runs.records import DaggerSchedule

    torch.manual_seed(0)
    # epochs: every sample exactly once per pass, the last batch of a pass shorter
    batches = list(distill.minibatches(10, DaggerSchedule(epochs=3, batch_size=4)))
    assert [len(b) for b in batches] == [4, 4, 2] * 3
    counts = torch.bincount(torch.cat(batches), minlength=10)
    assert counts.tolist() == [3] * 10
    # updates: that many full batches whatever the data set's size, indices in range
    for n in (5, 10_000):
        batches = list(distill.minibatches(n, DaggerSchedule(updates=7, batch_size=64)))
        assert len(batches) == 7 and all(len(b) == min(64, n) for b in batches)
        idx = torch.cat(batches)
        assert int(idx.min()) >= 0 and int(idx.max()) < n
    big = torch.cat(list(distill.minibatches(1000, DaggerSchedule(updates=200, batch_size=100))))
    counts = torch.bincount(big, minlength=1000).float()  # uniform: 20 draws each on average
    assert abs(float(counts.mean()) - 20.0) < 1e-9 and float(counts.std()) < 6.0
    with pytest.raises(UserError, match="--updates"):
        distill.parse_args(["--env", ENV_ID, "--teacher", "t", "--updates", "-1"])
    assert distill.parse_args(["--env", ENV_ID, "--teacher", "t"]).dagger.updates == 0


def test_iteration_rank_orders_by_success_then_strict_rate_or_error():
    def summary(success, strict, x_mm, theta_deg, failures=0.0):
        return {"success_rate": success, "success_strict": strict, "median_x_mm": x_mm,
                "median_theta_deg": theta_deg, "failure_rate": failures}

    targets = ("x", "theta")
    precise = summary(1.0, 0.95, 0.20, 0.30)  # more strict successes, larger median error
    close = summary(1.0, 0.90, 0.10, 0.20)
    better = summary(1.01, 0.0, 5.0, 5.0)  # a higher success rate outranks both
    for select, winner in (("success", close), ("strict", precise), ("safe", precise)):
        ranks = {id(s): distill.iteration_rank(s, targets, select)
                 for s in (precise, close, better)}
        assert max(ranks, key=ranks.get) == id(better)
        assert max((precise, close), key=lambda s: ranks[id(s)]) is winner
    # safe: a failure counts against the success rate, so 96 % with 1 % failures ranks below
    # 95.5 % without, and above 94 % without
    failing = summary(0.96, 0.9, 0.1, 0.1, failures=0.01)
    ranks = [distill.iteration_rank(s, targets, "safe")
             for s in (failing, summary(0.955, 0.5, 1, 1), summary(0.94, 0.9, 0.1, 0.1))]
    assert ranks[1] > ranks[0] > ranks[2]
    assert distill.iteration_rank(failing, targets, "success") > distill.iteration_rank(
        summary(0.955, 0.5, 1, 1), targets, "success")
    args = distill.parse_args(["--env", ENV_ID, "--teacher", "t", "--select", "strict"])
    assert args.dagger.select == "strict"
    assert distill.parse_args(["--env", ENV_ID, "--teacher", "t"]).dagger.select == "success"
    with pytest.raises(CliError, match="--select"):
        distill.parse_args(["--env", ENV_ID, "--teacher", "t", "--select", "loss"])
    from agents.runs.records import DaggerSchedule
    with pytest.raises(UserError, match="--select"):
        DaggerSchedule(select="loss")


def test_validation_counts_the_episodes_a_physical_failure_ends():
    """``failure_rate``: squeezing with both fingers at the largest step over-compresses the
    first step, holding the grasp does not; the count agrees with single-env episodes."""
    from agents.common.metrics import success_kwargs

    kwargs = {"control_dt": 0.16, "max_episode_steps": 12, "max_delta_deg": 8.0}
    venv = make_sb3_vec_env(ENV_ID, 6, 0, {**kwargs, **success_kwargs(ENV_ID)}, "native")
    squeeze = np.array([1, 0, 1, 0, 0, 0], dtype=np.float32)  # envs 0 and 2 squeeze

    class Policy:
        def predict(self, obs, deterministic=True):
            return np.repeat(squeeze[:, None], 2, axis=1), None

    summary = distill.validate(Policy(), venv, ("theta",), 5000)
    assert summary["failure_rate"] == pytest.approx(2 / 6)
    env = gym.make(ENV_ID, **kwargs)
    reasons = []
    for k in range(6):
        env.reset(seed=5000 + k)
        for _ in range(12):
            *_, terminated, truncated, info = env.step(np.full(2, squeeze[k], np.float32))
            if terminated or truncated:
                break
        reasons.append(info["termination_reason"])
    assert reasons[0] == reasons[2] == "overcompressed"
    assert all(r in (None, "success") for r in reasons[1:2] + reasons[3:])


def test_imitation_loss_is_the_squared_error_or_an_expectile_of_the_squeeze():
    gen = torch.Generator().manual_seed(0)
    pred, label = torch.randn(64, 2, generator=gen), torch.randn(64, 2, generator=gen)
    assert torch.equal(distill.imitation_loss(pred, label), ((label - pred) ** 2).mean())
    # tau = 0.5 through the weighted branch: the (rotate, squeeze) rotation keeps the norm
    # (float32: equal within a few roundings of 1.2e-7)
    mse = ((label - pred) ** 2).mean()
    assert torch.allclose(distill.imitation_loss(pred, label, 0.5 + 1e-12), mse, rtol=1e-6)
    # a pure squeeze error: closing more than the label costs 2 (1 - tau), less 2 tau
    zero, close = torch.zeros(1, 2), torch.tensor([[0.1, 0.1]])  # s = 0.1 sqrt 2
    over = distill.imitation_loss(close, zero, 0.2)  # the student closes more
    under = distill.imitation_loss(zero, close, 0.2)
    assert torch.allclose(over, torch.tensor(2 * 0.8 * 0.02 / 2))
    assert torch.allclose(under, torch.tensor(2 * 0.2 * 0.02 / 2))
    # a pure rotate error is not weighted
    turn = torch.tensor([[0.1, -0.1]])
    assert torch.allclose(distill.imitation_loss(turn, zero, 0.2), ((turn) ** 2).mean())
    # the constant prediction that minimises it is the tau-expectile of the labels' squeeze
    s_labels = torch.tensor([0.0, 0.0, 0.0, 1.0])  # one state, four labels
    labels = torch.stack([s_labels, s_labels], dim=1) / 2 ** 0.5
    a = torch.zeros(1, 2, requires_grad=True)
    opt = torch.optim.Adam([a], lr=0.02)
    for _ in range(3000):
        opt.zero_grad()
        distill.imitation_loss(a.expand(4, 2), labels, 0.2).backward()
        opt.step()
    s_fit = float(a.sum()) / 2 ** 0.5
    # expectile e of {0, 0, 0, 1}: 0.2 (1 - e) = 0.8 * 3 e -> e = 0.2 / 2.6
    assert s_fit == pytest.approx(0.2 / 2.6, abs=1e-4) and s_fit < float(s_labels.mean())
    assert abs(float(a[0, 0] - a[0, 1])) < 1e-4
    with pytest.raises(UserError, match="two-finger"):
        distill.imitation_loss(torch.zeros(2, 3), torch.ones(2, 3), 0.3)
    from agents.runs.records import DaggerSchedule
    for bad in (0.0, 1.0, float("nan")):
        with pytest.raises(UserError, match="--squeeze-expectile"):
            DaggerSchedule(squeeze_expectile=bad)
    args = distill.parse_args(["--env", ENV_ID, "--teacher", "t", "--squeeze-expectile", "0.3"])
    assert args.dagger.squeeze_expectile == 0.3
    assert distill.parse_args(["--env", ENV_ID, "--teacher", "t"]).dagger.squeeze_expectile == 0.5


def test_delayed_labels_pair_a_state_with_the_teacher_action_when_its_command_acts():
    labels = distill.DelayedLabels(3)
    latency = np.array([0, 1, 2])  # env i: commands take effect i steps later
    got = []
    for t in range(5):
        blind = np.full((3, 1), t, np.float32)  # the step, as the observation
        t_act = (10 * t + np.arange(3, dtype=np.float32))[:, None]  # step and env, as actions
        x, y = labels.step(blind, t_act, latency)
        got.append(sorted(zip(x[:, 0].tolist(), y[:, 0].tolist(), strict=True)))
        labels.end_step(np.array([False, False, t == 2]))  # env 2's episode ends at step 2
    # env 0: the same step; env 1: the next step; env 2: two steps later, and nothing of its
    # episode's steps 1 and 2 (it ended first); its next episode's step 3 is due at step 5
    assert got == [[(0, 0)], [(0, 11), (1, 10)], [(0, 22), (1, 21), (2, 20)],
                   [(2, 31), (3, 30)], [(3, 41), (4, 40)]]


def test_latency_labels_read_each_episodes_latency_from_the_step_infos_of_any_vec_env():
    """--latency-labels takes the latency from the step infos: an SB3 DummyVecEnv of single
    envs gives the native vector env's latencies (episode ends included), and the labels pair
    a state with the teacher action of its step + that episode's latency."""
    n, kw = 8, {"max_episode_steps": 3}
    dummy = make_sb3_vec_env("SoftHandPoseRandom-v0", n, 0, kw, "dummy")
    native = make_sb3_vec_env("SoftHandPoseRandom-v0", n, 0, kw, "native")
    dummy.reset()
    native.reset()
    first = np.array([info["setpoint_latency"] for info in dummy.reset_infos])
    labels, episode_latency = distill.DelayedLabels(n), {}
    episode = np.zeros(n, dtype=int)
    pairs = []
    for t in range(9):
        _, _, dones, infos = dummy.step(np.zeros((n, 2), np.float32))
        _, _, native_dones, native_infos = native.step(np.zeros((n, 2), np.float32))
        latency = distill.step_latencies(infos)
        assert latency.dtype == np.int64 and latency.shape == (n,)
        np.testing.assert_array_equal(latency, distill.step_latencies(native_infos))
        np.testing.assert_array_equal(dones, native_dones)
        if t == 0:
            np.testing.assert_array_equal(latency, first)  # the reset's draw
        for i in range(n):
            episode_latency[i, episode[i]] = int(latency[i])
        blind = np.stack([np.full(n, t), np.arange(n), episode], axis=1).astype(np.float32)
        x, y = labels.step(blind, (100 * t + np.arange(n, dtype=np.float32))[:, None], latency)
        pairs += list(zip(x.tolist(), y[:, 0].tolist(), strict=True))
        labels.end_step(dones)
        episode += dones
    assert {v for v in episode_latency.values()} == {0, 1} and episode.min() >= 2
    assert pairs
    for (step, env, ep), label in pairs:  # the teacher's action at step + L, same env
        assert label == 100 * (step + episode_latency[int(env), int(ep)]) + env
    with pytest.raises(UserError, match="setpoint_latency"):
        distill.step_latencies([{}])


def test_student_with_further_wrappers_feeds_the_teacher_without_their_features(tmp_path,
                                                                                 teacher):
    history = {"agents.action_history.ActionHistory": {"n": 2}}
    run = distill.main(_student_args(tmp_path, teacher, env_wrapper=WRAPPER + [history]))
    assert ModelPolicy(run).model.observation_space.shape == (8 + 1 + 1 + 4,)
    obs = {"observation": np.arange(14.0)[None], "privileged": np.zeros((1, 3))}
    view = distill.teacher_view(obs, distill.view_layout(KWARGS), distill.view_layout(KWARGS),
                                10)
    np.testing.assert_array_equal(view["observation"], np.arange(10.0)[None])
    with pytest.raises(UserError, match="must start with the teacher's"):
        distill.main(_student_args(tmp_path, teacher, env_wrapper=[history]))
