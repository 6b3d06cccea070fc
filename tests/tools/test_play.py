"""Keyboard teleoperation: the key map, ``python -m softhand_env.play`` and gymnasium's play,
driven headless (SDL dummy video driver) by posted key events."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from softhand_env.envs.keys import FINGER_KEYS, NOOP, action_from_keys, keys_to_action

pygame = pytest.importorskip("pygame")


@pytest.fixture(autouse=True)
def headless(monkeypatch):
    """No real window or audio device: SDL's dummy drivers."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    monkeypatch.setenv("SDL_AUDIODRIVER", "dummy")

ENV = "SoftHandPose-v0"


def test_key_map_moves_each_fingertip_in_the_key_direction():
    # finger 2 (left, action index 1): d closes (+), a opens; finger 1 (right): j closes, l opens
    assert keys_to_action()[("d",)].tolist() == [0.0, 1.0]
    assert keys_to_action()[("a",)].tolist() == [0.0, -1.0]
    assert keys_to_action()[("j",)].tolist() == [1.0, 0.0]
    assert keys_to_action()[("l",)].tolist() == [-1.0, 0.0]
    assert keys_to_action()[("a", "j")].tolist() == [1.0, -1.0]  # both tips left


def test_key_map_lists_singles_and_one_key_per_finger_pairs():
    mapping = keys_to_action()
    assert len(mapping) == 4 + 2 * 2
    for combo, action in mapping.items():
        assert combo == tuple(sorted(combo))
        assert action.dtype == np.float32 and action.shape == (2,)
        assert np.array_equal(action, action_from_keys(combo))
        assert len({FINGER_KEYS[k][0] for k in combo}) == len(combo)  # one key per finger
    assert np.array_equal(action_from_keys(["a", "d", "x"]), NOOP)  # opposite keys cancel


def test_env_exposes_the_key_map_in_delta_mode_only():
    env = gym.make(ENV)
    mapping = env.unwrapped.get_keys_to_action()
    assert all(a in env.action_space for a in mapping.values())
    env.close()
    env = gym.make(ENV, action_mode="absolute")
    with pytest.raises(ValueError, match="action_mode='delta'"):
        env.unwrapped.get_keys_to_action()
    env.close()


def post_key(kind: int, name: str) -> None:
    pygame.event.post(pygame.event.Event(kind, key=pygame.key.key_code(name)))


def test_play_window_moves_set_points_with_held_keys_and_draws_the_overlay():
    from softhand_env.play import Teleop

    env = gym.make(ENV, render_mode="rgb_array", render_width=200, render_height=200)
    teleop = Teleop(env, seed=1, speed=10.0)
    try:
        u0 = np.degrees(teleop.info["setpoint"])
        assert "goal  x* = " in "\n".join(teleop.lines()) and "θ* = " in "\n".join(teleop.lines())
        post_key(pygame.KEYDOWN, "d")  # left tip right: theta_2^d up 1 deg per step
        teleop.run(max_frames=5)
        post_key(pygame.KEYUP, "d")
        post_key(pygame.KEYDOWN, "l")  # right tip right: theta_1^d down
        summary = teleop.run(max_frames=3)
        u = np.array(summary["setpoint_deg"])
        assert u[1] - u0[1] == pytest.approx(5.0, abs=1e-6)
        assert u[0] - u0[0] == pytest.approx(-3.0, abs=1e-6)
        assert summary["steps"] == 8
        assert teleop.lines()[0] == "t = 0.16 s"  # 8 steps of 20 ms
        drawn = pygame.surfarray.array3d(teleop.screen).swapaxes(0, 1)
        plain = env.render()
        assert drawn.shape == plain.shape
        assert not np.array_equal(drawn[:20, :60], plain[:20, :60])  # the text box is there
        post_key(pygame.KEYDOWN, "r")
        teleop.run(max_frames=1)
        assert teleop.episodes == 2 and teleop.steps == 1
        pygame.event.post(pygame.event.Event(pygame.QUIT))
        assert teleop.run(max_frames=10)["frames"] == 1 and not teleop.running
    finally:
        teleop.close()


def test_play_cli_runs_headless_and_validates_options(capsys):
    from softhand_env.play import main

    assert main(["--env", "SoftHandTranslate-v0", "--size", "160", "--max-frames", "3",
                 "--speed", "10", "--seed", "0"]) == 0
    assert "1 episode(s), 3 steps" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main(["--speed", "0"])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        main(["--env", "NoSuchEnv-v0", "--max-frames", "1"])
    assert exc.value.code == 2


@pytest.mark.filterwarnings("ignore:.*matplotlib is not installed")
def test_gymnasium_play_uses_the_env_key_map():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401  (pyplot on Agg: gymnasium's import cannot switch it)
    from gymnasium.utils.play import play

    env = gym.make(ENV, render_mode="rgb_array", render_width=120, render_height=120)
    seen: list[np.ndarray] = []

    def callback(obs_t, obs_tp1, action, rew, terminated, truncated, info):
        seen.append(np.asarray(info["setpoint"]).copy())
        if len(seen) == 1:
            post_key(pygame.KEYDOWN, "j")  # right tip left: theta_1^d up
        if len(seen) == 6:
            pygame.event.post(pygame.event.Event(pygame.QUIT))

    play(env, fps=1000, noop=NOOP, seed=0, callback=callback)
    env.close()
    step = np.degrees(seen[-1] - seen[0])  # steps 2-6 with the key held
    assert matplotlib.get_backend().lower() == "agg"
    assert step[0] == pytest.approx(5.0, abs=1e-6) and step[1] == pytest.approx(0.0, abs=1e-9)
