"""Policies for Dict observations whose actor stays blind (asymmetric actor-critic).

With ``privileged_obs=True`` or ``goal_obs=True`` (:mod:`softhand_env.envs.dict_obs`) the
observation holds keys a blind agent must not act on: ``privileged`` (object pose, velocity,
deformations, drawn parameters) and ``achieved_goal`` (the object's pose, for hindsight
relabelling). The policies here give the actor only :data:`ACTOR_KEYS` present in the space
(``observation`` and ``desired_goal``) and the critic every key, as in asymmetric
actor-critic training (Pinto et al., 2017): the critic is used only during training, so
the deployed policy is as blind as before.

* :class:`KeyConcat`: features extractor concatenating chosen keys of a Dict observation.
* :class:`AsymmetricActorCriticPolicy` (PPO/A2C, alias ``AsymmetricPolicy``): separate
  actor and critic extractors and MLPs (``net_arch`` as for ``MultiInputPolicy``).
* :class:`BlindActorSACPolicy` (SAC, alias ``BlindActorPolicy``; for SAC + HER): the actor
  reads ``observation`` + ``desired_goal``, the Q networks every key.

Importing this module registers the aliases with PPO, A2C and SAC, so a hyper-parameter file
may say ``policy: AsymmetricPolicy`` (``python -m agents.train`` imports it; with RL Zoo add
``--gym-packages agents.sb3.policies``). ``actor_keys`` / ``critic_keys`` in ``policy_kwargs``
override the defaults.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch as th
from gymnasium import spaces
from stable_baselines3 import A2C, PPO, SAC
from stable_baselines3.common.policies import MultiInputActorCriticPolicy
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, MlpExtractor
from stable_baselines3.sac.policies import MultiInputPolicy as SACMultiInputPolicy
from torch import nn

#: Keys the actor reads by default (those present in the observation space).
ACTOR_KEYS = ("observation", "desired_goal")


#: Policy keywords the blind-actor policies set themselves (the per-key extractors).
_EXTRACTOR_KWARGS = ("features_extractor_class", "features_extractor_kwargs",
                     "share_features_extractor")


def mean_action(policy: Any, obs: Any) -> Any:
    """Mean action (torch (B, act_dim)) of an SB3 ActorCriticPolicy for observations ``obs``
    (torch (B, obs_dim)): what DAgger and behaviour cloning fit to their labels."""
    features = policy.extract_features(obs, policy.pi_features_extractor)
    return policy.action_net(policy.mlp_extractor.forward_actor(features))


def _refuse_extractor_kwargs(policy: str, kwargs: dict[str, Any]) -> None:
    """ValueError if ``kwargs`` tries to set what the blind-actor policy ``policy`` sets."""
    for key in _EXTRACTOR_KWARGS:
        if key in kwargs:
            raise ValueError(f"{policy} sets {key} itself")


def _set_keys(policy: Any, observation_space: spaces.Dict, actor_keys: Sequence[str] | None,
              critic_keys: Sequence[str] | None, kwargs: dict[str, Any]) -> None:
    """Shared start of the blind-actor policies' constructors: ``policy._keys`` (actor keys,
    critic keys; defaults: ``ACTOR_KEYS`` present, every key) and ``policy._dict_space``, after
    refusing extractor keywords in ``kwargs``."""
    policy._keys = (
        resolve_keys(observation_space, actor_keys, ACTOR_KEYS),
        resolve_keys(observation_space, critic_keys, tuple(observation_space.spaces)),
    )
    policy._dict_space = observation_space
    _refuse_extractor_kwargs(type(policy).__name__, kwargs)


def _split_key_parameters(data: dict[str, Any],
                          keys: tuple[Sequence[str], Sequence[str]]) -> dict[str, Any]:
    """Constructor parameters saved with a blind-actor policy: the actor/critic keys instead of
    the extractor keywords (rebuilt from the keys on load)."""
    for key in _EXTRACTOR_KWARGS:
        data.pop(key, None)
    data.update(actor_keys=list(keys[0]), critic_keys=list(keys[1]))
    return data


def resolve_keys(space: spaces.Space, keys: Sequence[str] | None, default: Sequence[str]):
    """The keys of ``space`` to read: ``keys`` (all must exist) or the ``default`` ones present.

    Raises
    ------
    TypeError
        ``space`` is not a Dict space.
    ValueError
        A requested key is missing, or no key is left.
    """
    if not isinstance(space, spaces.Dict):
        raise TypeError(f"these policies need a Dict observation space (got {space})")
    if keys is None:
        out = tuple(k for k in default if k in space.spaces)
    else:
        out = tuple(keys)
        missing = [k for k in out if k not in space.spaces]
        if missing:
            raise ValueError(f"observation has no key(s) {missing} (keys: {list(space.spaces)})")
    if not out:
        raise ValueError(f"no observation key to read among {list(space.spaces)}")
    return out


class KeyConcat(BaseFeaturesExtractor):
    """Flattens and concatenates ``keys`` of a Dict observation, in that order.

    Parameters
    ----------
    observation_space : spaces.Dict
    keys : sequence of str
        Keys to read; every other key is ignored (it cannot influence the output).
    """

    def __init__(self, observation_space: spaces.Dict, keys: Sequence[str]):
        keys = resolve_keys(observation_space, keys, ())
        dim = sum(get_flattened_obs_dim(observation_space[k]) for k in keys)
        super().__init__(observation_space, features_dim=dim)
        self.keys = keys

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        return th.cat([th.flatten(observations[k], start_dim=1) for k in self.keys], dim=1)


class _SplitMlp(nn.Module):
    """Actor and critic MLPs on inputs of different widths (MlpExtractor's interface)."""

    def __init__(self, pi_dim: int, vf_dim: int, net_arch: Any, activation_fn: type[nn.Module],
                 device: Any):
        super().__init__()
        pi = MlpExtractor(pi_dim, net_arch, activation_fn, device)
        vf = MlpExtractor(vf_dim, net_arch, activation_fn, device)
        self.policy_net, self.value_net = pi.policy_net, vf.value_net
        self.latent_dim_pi, self.latent_dim_vf = pi.latent_dim_pi, vf.latent_dim_vf

    def forward(self, features: tuple[th.Tensor, th.Tensor]) -> tuple[th.Tensor, th.Tensor]:
        return self.forward_actor(features[0]), self.forward_critic(features[1])

    def forward_actor(self, features: th.Tensor) -> th.Tensor:
        return self.policy_net(features)

    def forward_critic(self, features: th.Tensor) -> th.Tensor:
        return self.value_net(features)


class AsymmetricActorCriticPolicy(MultiInputActorCriticPolicy):
    """Actor-critic policy: the actor reads ``actor_keys``, the critic ``critic_keys``.

    Parameters
    ----------
    actor_keys : sequence of str, optional
        Default: those of :data:`ACTOR_KEYS` in the space.
    critic_keys : sequence of str, optional
        Default: every key.
    **kwargs
        As for SB3's ``MultiInputActorCriticPolicy`` (``features_extractor_class`` and
        ``share_features_extractor`` are fixed here).
    """

    #: Actor keys and critic keys of the Dict observation, and that Dict space (_set_keys).
    _keys: tuple[Sequence[str], Sequence[str]]
    _dict_space: spaces.Dict

    def __init__(self, observation_space: spaces.Dict, action_space: spaces.Space,
                 lr_schedule: Any, actor_keys: Sequence[str] | None = None,
                 critic_keys: Sequence[str] | None = None, **kwargs: Any):
        _set_keys(self, observation_space, actor_keys, critic_keys, kwargs)
        self._n_made = 0
        super().__init__(observation_space, action_space, lr_schedule,
                         share_features_extractor=False, **kwargs)

    def make_features_extractor(self) -> BaseFeaturesExtractor:
        """The actor's extractor on the first call, the critic's on the second."""
        keys = self._keys[min(self._n_made, 1)]
        self._n_made += 1
        return KeyConcat(self._dict_space, keys)

    def _build_mlp_extractor(self) -> None:
        self.mlp_extractor = _SplitMlp(  # type: ignore[assignment]
            self.pi_features_extractor.features_dim, self.vf_features_extractor.features_dim,
            self.net_arch, self.activation_fn, self.device,
        )

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return _split_key_parameters(super()._get_constructor_parameters(), self._keys)


class BlindActorSACPolicy(SACMultiInputPolicy):
    """SAC policy: the actor reads ``actor_keys``, the Q networks ``critic_keys``.

    For SAC + HER on ``goal_obs=True``: the actor sees ``observation`` + ``desired_goal``;
    ``achieved_goal`` reaches only the critics (and the relabelling). Parameters as
    :class:`AsymmetricActorCriticPolicy`.
    """

    #: Actor keys and critic keys of the Dict observation, and that Dict space (_set_keys).
    _keys: tuple[Sequence[str], Sequence[str]]
    _dict_space: spaces.Dict

    def __init__(self, observation_space: spaces.Dict, action_space: spaces.Space,
                 lr_schedule: Any, actor_keys: Sequence[str] | None = None,
                 critic_keys: Sequence[str] | None = None, **kwargs: Any):
        _set_keys(self, observation_space, actor_keys, critic_keys, kwargs)
        super().__init__(observation_space, action_space, lr_schedule,  # type: ignore[arg-type]
                         share_features_extractor=False, **kwargs)

    def make_actor(self, features_extractor: BaseFeaturesExtractor | None = None):
        return super().make_actor(KeyConcat(self._dict_space, self._keys[0]))

    def make_critic(self, features_extractor: BaseFeaturesExtractor | None = None):
        return super().make_critic(KeyConcat(self._dict_space, self._keys[1]))

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return _split_key_parameters(super()._get_constructor_parameters(), self._keys)


#: Policy aliases registered with SB3 on import.
POLICY_ALIASES: dict[Any, dict[str, type]] = {
    PPO: {"AsymmetricPolicy": AsymmetricActorCriticPolicy},
    A2C: {"AsymmetricPolicy": AsymmetricActorCriticPolicy},
    SAC: {"BlindActorPolicy": BlindActorSACPolicy},
}
for _algo, _aliases in POLICY_ALIASES.items():
    _algo.policy_aliases = {**_algo.policy_aliases, **_aliases}  # type: ignore[attr-defined,unused-ignore]
