"""Observability tool: pose regression from observation frames on held-out episodes."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("torch")

from softhand_env.cli import CliError  # noqa: E402
from softhand_env.envs.observation import ANGLE_SCALE  # noqa: E402
from softhand_env.envs.sensors import load_sensor_spec  # noqa: E402
from softhand_env.tools import observability as ob  # noqa: E402

SMALL = {"episodes": 8, "max_steps": 60}
FIT = {"frames": (1, 2), "epochs": 40, "hidden": (64, 64)}


@pytest.fixture(scope="module")
def data() -> ob.Episodes:
    return ob.collect("SoftHandPose-v0", None, SMALL["episodes"], "scripted", seed=3,
                      max_steps=SMALL["max_steps"])


def test_collect_shapes_and_blind_frames(data):
    assert len(data.frames) == len(data.poses) == SMALL["episodes"]
    assert data.frame_size == 8  # proprio frame, goal entries and history left out
    for fr, po in zip(data.frames, data.poses, strict=True):
        assert fr.shape == (len(po), 8) and po.shape[1] == 3
        assert 2 <= len(po) <= SMALL["max_steps"] + 1
    # the walk moves the object: x spans millimetres across the data
    x = np.concatenate([p[:, 0] for p in data.poses])
    assert x.max() - x.min() > 2e-3


def test_stack_frames_pads_with_the_first_frame():
    frames = np.arange(10.0).reshape(5, 2)
    s = ob.stack_frames(frames, 3)
    assert s.shape == (5, 6)
    np.testing.assert_array_equal(s[0], [0, 1, 0, 1, 0, 1])
    np.testing.assert_array_equal(s[3], [6, 7, 4, 5, 2, 3])


def test_split_is_by_episode_and_seeded():
    train, test = ob.split_episodes(8, 0.25, seed=1)
    assert len(test) == 2 and len(train) == 6 and not set(train) & set(test)
    again = ob.split_episodes(8, 0.25, seed=1)
    np.testing.assert_array_equal(train, again[0])
    with pytest.raises(ValueError, match="at least 2"):
        ob.split_episodes(1, 0.25, seed=1)


def test_table_units_and_mean_baseline(data):
    rows = ob.observability(data, seed=0, **FIT)
    assert [r.label for r in rows] == ["mean", "1 frame", "2 frames"]
    train, test = ob.split_episodes(len(data.frames), 0.25, 0)
    y_test = np.vstack([data.poses[e] for e in test])
    y_train = np.vstack([data.poses[e] for e in train])
    err = y_test - y_train.mean(0)
    # the baseline row is the held-out RMSE of the training mean, in mm and deg
    assert rows[0].rmse_x_mm == pytest.approx(1e3 * np.sqrt(np.mean(err[:, 0] ** 2)))
    assert rows[0].rmse_theta_deg == pytest.approx(math.degrees(np.sqrt(np.mean(err[:, 2] ** 2))))
    assert all(r.n_frames == len(y_test) for r in rows)
    assert all(0.0 <= r.within_strict <= r.within <= 1.0 for r in rows)
    table = ob.format_table("t", rows)
    assert "RMSE x (mm)" in table and "RMSE theta (deg)" in table
    assert "within 0.5 mm and 0.5 deg" in table
    assert len(table.splitlines()) == 4 + len(rows)


def test_score_counts_both_tolerances():
    true = np.zeros((4, 3))
    # errors (x mm, theta deg): inside both boxes, inside 1/1 only (x), inside 1/1 only
    # (theta), outside both
    err = np.array([[0.4, 0.0, 0.4], [0.7, 0.0, 0.1], [0.1, 0.0, 0.8], [1.2, 0.0, 0.1]])
    pred = np.column_stack([1e-3 * err[:, 0], err[:, 1], np.radians(err[:, 2])])
    row = ob.score("r", pred, true)
    assert row.within == pytest.approx(3 / 4)
    assert row.within_strict == pytest.approx(1 / 4)


def test_fit_beats_shuffled_labels_and_is_deterministic(data):
    rows = ob.observability(data, seed=0, **FIT)
    again = ob.observability(data, seed=0, **FIT)
    assert rows == again
    shuffled = ob.observability(data, seed=0, shuffle_labels=True, **FIT)
    for real, nonsense in zip(rows[1:], shuffled[1:], strict=True):
        # the frames carry the pose (the PID torques balance the contact forces): a fit on
        # the real labels is far better than one on labels permuted across frames, which
        # can do no better than the mean
        assert real.rmse_x_mm < 0.3 * nonsense.rmse_x_mm
        assert real.rmse_theta_deg < 0.3 * nonsense.rmse_theta_deg
        assert real.within > nonsense.within + 0.3
        assert nonsense.rmse_x_mm > 0.7 * rows[0].rmse_x_mm


def test_random_policy_and_cli(capsys):
    assert ob.main(["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "4",
                    "--max-steps", "20", "--epochs", "5", "--hidden", "16", "--frames", "1",
                    "--env-kwargs", "obs_mode:proprio_tactile", "obs_noise:0.01"]) == 0
    out = capsys.readouterr().out
    assert "obs_mode:proprio_tactile obs_noise:0.01" in out and "random policy" in out
    assert out.count("| 1 frame |") == 1 and "| mean |" in out


def test_cli_errors():
    with pytest.raises(CliError, match="--episodes must be >= 2"):
        ob.main(["--env", "SoftHandPose-v0", "--episodes", "1"])
    with pytest.raises(CliError, match="key:value"):
        ob.main(["--env", "SoftHandPose-v0", "--env-kwargs", "obs_noise"])
    with pytest.raises(CliError, match="cannot roll out"):
        ob.main(["--env", "SoftHandPose-v0", "--env-kwargs", "obs_mode:vision",
                 "--episodes", "2"])
    with pytest.raises(CliError, match="invalid choice: 'exact'"):
        ob.main(["--env", "SoftHandPose-v1", "--sensor-model", "exact"])
    with pytest.raises(CliError, match="invalid choice: 'vision'"):
        ob.main(["--env", "SoftHandPose-v1", "--obs-mode", "vision"])
    with pytest.raises(CliError, match="invalid choice: 'velocity'"):
        ob.main(["--env", "SoftHandPose-v1", "--target", "velocity"])
    with pytest.raises(CliError, match="sensor_model is given twice"):
        ob.main(["--env", "SoftHandPose-v1", "--sensor-model", "ideal",
                 "--env-kwargs", "sensor_model:realistic"])


def test_sensing_options_become_env_keywords():
    assert ob.env_kwargs(["obs_noise:0.01"]) == {"obs_noise": 0.01}
    assert ob.env_kwargs([], "realistic", "proprio_tactile") == {
        "sensor_model": "realistic", "obs_mode": "proprio_tactile"}
    # ideal read-outs have no gains to draw: the Random -v1 ids' rand_sensors goes off, unless
    # the user sets it
    assert ob.env_kwargs([], "ideal") == {"sensor_model": "ideal", "rand_sensors": False}
    assert ob.env_kwargs(["rand_sensors:true"], "ideal")["rand_sensors"] is True


def test_sensor_model_changes_the_frames_not_the_episodes():
    """The same seeded walk on SoftHandPose-v1 read with realistic and with ideal sensing:
    the object moves the same (the sensor model draws after the physics), the frames differ
    by the sensors' errors (angles quantised to 360/4096 deg in scaled units), and the
    episodes record their sensing."""
    kw = {"episodes": 2, "policy": "scripted", "seed": 7, "max_steps": 15}
    real = ob.collect("SoftHandPose-v1", None, **kw)
    ideal = ob.collect("SoftHandPose-v1", {"sensor_model": "ideal"}, **kw)
    tactile = ob.collect("SoftHandPose-v1", {"obs_mode": "proprio_tactile"}, **kw)
    assert real.sensing == {"sensor_model": "realistic", "obs_mode": "proprio",
                            "obs_noise": 0.0, "rand_sensors": False}
    assert ideal.sensing["sensor_model"] == "ideal"
    assert tactile.sensing["obs_mode"] == "proprio_tactile" and tactile.frame_size == 12
    for a, b in zip(real.poses, ideal.poses, strict=True):
        np.testing.assert_array_equal(a, b)
    diff = np.abs(np.vstack(real.frames) - np.vstack(ideal.frames))
    assert diff.max() > 1e-4
    # the angle entries (first two, theta / ANGLE_SCALE, float32) of a realistic frame are
    # whole encoder counts; the ideal ones are not
    count = math.radians(load_sensor_spec("realistic").encoder_resolution_deg)
    counts = np.vstack(real.frames)[:, :2] * ANGLE_SCALE / count
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-3)
    exact = np.vstack(ideal.frames)[:, :2] * ANGLE_SCALE / count
    assert np.abs(exact - np.round(exact)).max() > 0.1
    assert "sensor_model realistic, obs_mode proprio, obs_noise 0" == ob.sensing_text(real.sensing)


def test_cli_sensing_in_the_title(capsys):
    assert ob.main(["--env", "SoftHandPoseRandom-v1", "--obs-mode", "proprio_tactile",
                    "--episodes", "3", "--max-steps", "10", "--epochs", "2", "--hidden", "8",
                    "--frames", "1"]) == 0
    out = capsys.readouterr().out
    assert ("SoftHandPoseRandom-v1 (obs_mode:proprio_tactile; sensor_model realistic, "
            "obs_mode proprio_tactile, obs_noise 0.01, rand_sensors)") in out


def test_score_compression_counts_the_deep_readings_and_both_fingers():
    true = np.array([[9.0, 4.0], [5.0, 5.0], [9.5, 9.2]]) * 1e-3
    err = np.array([[-0.6, 0.1], [0.2, -0.3], [-0.2, 0.4]]) * 1e-3
    row = ob.score_compression("r", true + err, true)
    assert row.rmse_mm == pytest.approx(1e3 * math.sqrt(np.mean(err**2)))
    deep = err[true > 8.5e-3]  # -0.6, -0.2, 0.4 mm
    assert row.n_deep == 3 and row.bias_deep_mm == pytest.approx(1e3 * deep.mean())
    assert row.rmse_deep_mm == pytest.approx(1e3 * math.sqrt(np.mean(deep**2)))
    assert row.within == pytest.approx(2 / 3)  # the first frame's -0.6 mm is outside
    shallow = ob.score_compression("r", true * 0.5, true * 0.5)
    assert math.isnan(shallow.rmse_deep_mm) and shallow.n_deep == 0


def test_compression_target_reads_the_onset_entries_when_the_env_has_them():
    # a randomised object width: where contact began differs per episode
    kwargs = {"rand_width": 0.2}
    plain = ob.collect("SoftHandPose-v0", kwargs, 6, "scripted", seed=0, max_steps=30)
    onset = ob.collect("SoftHandPose-v0", {**kwargs, "onset_obs": True}, 6, "scripted",
                       seed=0, max_steps=30)
    assert (plain.frame_size, onset.frame_size) == (8, 10)
    for fr, fo, dn in zip(plain.frames, onset.frames, onset.compressions, strict=True):
        np.testing.assert_array_equal(fo[:, :8], fr)  # ideal sensors: the same frames
        assert np.all(fo[:, 8:] == fo[0, 8:]) and np.all(fo[0, 8:] != 0)  # one onset each
        assert dn.shape == (len(fr), 2) and np.all(dn > 0)  # grasped: both compressed
    rows = ob.observability(onset, seed=0, target="compression", **FIT)
    assert [r.label for r in rows] == ["mean", "1 frame", "2 frames"]
    assert all(isinstance(r, ob.CompressionRow) for r in rows)
    table = ob.format_table("t", rows)
    assert "RMSE d_n (mm)" in table and len(table.splitlines()) == 4 + len(rows)
    with pytest.raises(ValueError, match="target"):
        ob.observability(onset, target="velocity")


def test_cli_compression_table(capsys):
    assert ob.main(["--env", "SoftHandPoseRandom-v1", "--target", "compression",
                    "--env-kwargs", "onset_obs:true", "--episodes", "4", "--max-steps", "10",
                    "--epochs", "5", "--frames", "1"]) == 0
    out = capsys.readouterr().out
    assert "onset_obs:True" in out and "target d_n1, d_n2" in out
    assert "| 1 frame |" in out and "both within 0.5 mm" in out
