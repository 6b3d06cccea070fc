"""Fine-tuning settings (agents.sb3.finetune): the critic warm-up freezes the actor, --log-std."""

from __future__ import annotations

import gymnasium as gym
import pytest
import torch
from stable_baselines3 import PPO

from agents import train
from agents.common.cli import UserError
from agents.runs import loading
from agents.sb3 import finetune

#: A tiny PPO run on the soft hand: 2 envs x 64 steps per update.
TINY_PPO = ["--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1"]


def _snapshot(params):
    return [p.detach().clone() for p in params]


def _changed(before, params):
    return [not torch.equal(a, p.detach()) for a, p in zip(before, params, strict=True)]


def test_actor_and_critic_parameters_partition_the_policy():
    model = PPO("MlpPolicy", gym.make("Pendulum-v1"), n_steps=64, batch_size=64, seed=0,
                policy_kwargs={"net_arch": {"pi": [8], "vf": [8]}})
    actor = finetune.actor_parameters(model.policy)
    critic = finetune.critic_parameters(model.policy)
    ids = [id(p) for p in actor + critic]
    assert len(ids) == len(set(ids)) == len(list(model.policy.parameters()))
    assert any(p is model.policy.log_std for p in actor)
    assert all(any(p is q for p in critic) for q in model.policy.value_net.parameters())


def test_warmup_fits_the_critic_alone_then_both():
    model = PPO("MlpPolicy", gym.make("Pendulum-v1"), n_steps=64, batch_size=64, n_epochs=2,
                learning_rate=1e-3, seed=0, policy_kwargs={"net_arch": {"pi": [8], "vf": [8]}})
    actor = finetune.actor_parameters(model.policy)
    critic = finetune.critic_parameters(model.policy)
    a0, c0 = _snapshot(actor), _snapshot(critic)
    lrs: list[float] = []
    real_update = model._update_learning_rate

    def spy(optimizers):
        real_update(optimizers)
        lrs.append(model.policy.optimizer.param_groups[0]["lr"])

    model._update_learning_rate = spy
    warm = finetune.CriticWarmup(steps=192, lr=0.02)
    model.learn(128, callback=warm)  # two rollouts of 64 steps, ending before 192
    assert not any(_changed(a0, actor))  # the actor never moved
    assert all(_changed(c0, critic))  # every critic tensor did
    assert lrs == [0.02, 0.02]
    a1 = _snapshot(actor)
    model.learn(64, callback=warm, reset_num_timesteps=False)  # ends at 192: both train
    assert all(_changed(a1, actor))
    assert lrs[-1] == pytest.approx(1e-3)  # the algorithm's own schedule again
    assert all(p.requires_grad for p in model.policy.parameters())


def test_set_log_std_and_its_refusals():
    model = PPO("MlpPolicy", gym.make("Pendulum-v1"), n_steps=64, batch_size=64, seed=0)
    finetune.set_log_std(model, -3.0)
    assert torch.equal(model.policy.log_std.detach(), torch.full((1,), -3.0))
    discrete = PPO("MlpPolicy", gym.make("CartPole-v1"), n_steps=64, batch_size=64, seed=0)
    with pytest.raises(UserError, match="--log-std"):
        finetune.set_log_std(discrete, -3.0)


@pytest.mark.parametrize("kwargs,fragment", [
    ({"critic_warmup": -1}, "--critic-warmup"),
    ({"critic_warmup_lr": 0.0}, "--critic-warmup-lr"),
    ({"critic_warmup_lr": float("inf")}, "--critic-warmup-lr"),
    ({"log_std": 2.5}, "--log-std"),
    ({"log_std": float("nan")}, "--log-std"),
])
def test_settings_are_range_checked(kwargs, fragment):
    with pytest.raises(UserError, match=fragment):
        finetune.FineTune(**kwargs)


def test_training_cli_records_the_finetune_settings(tmp_path):
    base = ["--env", "SoftHandReorient-v0", "--n-timesteps", "128", "--eval-freq", "0",
            "--save-freq", "0", "--log-folder", str(tmp_path), "--no-progress-bar",
            "--verbose", "0", *TINY_PPO]
    plain = loading.ModelPolicy(train.main(base)).run.record
    assert plain["finetune"] is None
    run = train.main([*base, "--critic-warmup", "129", "--critic-warmup-lr", "0.01",
                      "--log-std", "-2.5"])
    policy = loading.ModelPolicy(run)
    assert policy.run.record["finetune"] == {"critic_warmup": 129, "critic_warmup_lr": 0.01,
                                             "log_std": -2.5}
    # the warm-up covered the whole run: the log std is still the one set at the start
    assert torch.equal(policy.model.policy.log_std.detach(), torch.full((2,), -2.5))
