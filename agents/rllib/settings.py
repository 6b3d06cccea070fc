"""The PPO entry of ``agents/configs/ppo.yml`` as RLlib settings (no Ray import here).

RLlib trains the network of the entry so that its export is an ordinary SB3 PPO run
(:mod:`agents.rllib.export`): separate actor and critic MLPs of the same widths
(``net_arch.pi == net_arch.vf``), the entry's activation, a state-independent log standard
deviation started at ``log_std_init`` (RLlib's ``free_log_std``), the Gaussian's mean clipped to
the action space (``clip_actions``, no squashing: SB3's ``predict``). What RLlib does not
offer the same way is refused (:class:`~agents.common.cli.UserError`): schedules,
``MultiInputPolicy`` / Dict observations, ``clip_range_vf``, gSDE. Observation normalisation
(``normalize.norm_obs``) is RLlib's ``MeanStdFilter`` (clipped at 10 as VecNormalize);
reward normalisation (``norm_reward``) has no RLlib counterpart and is off.

SB3 key -> RLlib: ``gamma`` -> ``gamma``, ``gae_lambda`` -> ``lambda_``, ``learning_rate``
-> ``lr``, ``clip_range`` -> ``clip_param``, ``n_epochs`` -> ``num_epochs``, ``batch_size``
-> ``minibatch_size``, ``n_envs * n_steps`` -> ``train_batch_size_per_learner``,
``ent_coef`` -> ``entropy_coeff``, ``vf_coef`` -> ``vf_loss_coeff``, ``max_grad_norm`` ->
``grad_clip`` (global norm); no KL penalty and no value clipping (SB3 has neither).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from agents.common.cli import UserError
from agents.runs.zoo_dialect import normalize_from, policy_kwargs_from

#: SB3's PPO defaults of the keys read here.
SB3_DEFAULTS: dict[str, Any] = {
    "n_envs": 1, "n_steps": 2048, "batch_size": 64, "n_epochs": 10, "gamma": 0.99,
    "gae_lambda": 0.95, "learning_rate": 3e-4, "clip_range": 0.2, "ent_coef": 0.0,
    "vf_coef": 0.5, "max_grad_norm": 0.5, "log_std_init": 0.0,
}
#: Entry keys that change nothing RLlib trains (or that the export writes as they are).
IGNORED_KEYS = ("n_timesteps", "env_kwargs", "env_wrapper", "normalize", "policy",
                "policy_kwargs", "vec_env", "device", "verbose", "seed")
#: Activations of SB3's ``activation_fn`` that RLlib's ``fcnet_activation`` names.
ACTIVATIONS = {"Tanh": "tanh", "ReLU": "relu", "SiLU": "silu", "ELU": "elu"}
#: VecNormalize's clip of normalised observations, also the filter's.
CLIP_OBS = 10.0


@dataclass(frozen=True)
class PPOSettings:
    """RLlib PPO settings of a ``ppo.yml`` entry (module doc): hidden widths, activation
    (RLlib's name), initial log std, the PPO coefficients, the train batch (env steps per
    iteration) and whether observations are normalised."""

    hidden: tuple[int, ...]
    activation: str
    log_std_init: float
    gamma: float
    lambda_: float
    lr: float
    clip_param: float
    num_epochs: int
    minibatch_size: int
    train_batch_size: int
    entropy_coeff: float
    vf_loss_coeff: float
    grad_clip: float | None
    norm_obs: bool

    def training_kwargs(self) -> dict[str, Any]:
        """Keywords of ``PPOConfig.training``."""
        return {
            "gamma": self.gamma, "lambda_": self.lambda_, "lr": self.lr,
            "clip_param": self.clip_param, "num_epochs": self.num_epochs,
            "minibatch_size": self.minibatch_size,
            "train_batch_size_per_learner": self.train_batch_size,
            "entropy_coeff": self.entropy_coeff, "vf_loss_coeff": self.vf_loss_coeff,
            "grad_clip": self.grad_clip, "grad_clip_by": "global_norm",
            "use_kl_loss": False, "kl_coeff": 0.0, "vf_clip_param": float("inf"),
        }


def _number(hp: dict[str, Any], key: str) -> float:
    value = hp.get(key, SB3_DEFAULTS[key])
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise UserError(f"RLlib training needs a constant {key} (got {value!r}; schedules "
                        "are not translated)")
    return float(value)


def ppo_settings(hp: dict[str, Any]) -> PPOSettings:
    """:class:`PPOSettings` of the PPO entry ``hp`` (a ``ppo.yml`` entry, RL Zoo's dialect);
    :class:`UserError` for what RLlib would train differently (module doc)."""
    if hp.get("policy") != "MlpPolicy":
        raise UserError(f"RLlib training exports MlpPolicy runs (the entry has policy "
                        f"{hp.get('policy')!r})")
    unknown = sorted(set(hp) - set(SB3_DEFAULTS) - set(IGNORED_KEYS))
    if unknown:
        raise UserError(f"the entry's {', '.join(unknown)} cannot be translated to RLlib")
    try:
        kwargs = policy_kwargs_from(hp.get("policy_kwargs") or {})
        norm = normalize_from(hp.get("normalize", False))
    except (TypeError, ValueError) as exc:
        raise UserError(f"policy_kwargs/normalize: {exc}") from None
    extra = sorted(set(kwargs) - {"net_arch", "activation_fn", "log_std_init", "ortho_init"})
    if extra:
        raise UserError(f"policy_kwargs {', '.join(extra)} cannot be translated to RLlib")
    arch = kwargs.get("net_arch", [64, 64])
    if isinstance(arch, dict):
        if arch.get("pi") != arch.get("vf") or set(arch) != {"pi", "vf"}:
            raise UserError("RLlib's actor and critic MLPs have the same widths: net_arch "
                            f"needs pi == vf (got {arch!r})")
        arch = arch["pi"]
    if not (isinstance(arch, list) and arch and all(
            isinstance(w, int) and not isinstance(w, bool) and w >= 1 for w in arch)):
        raise UserError(f"net_arch must be a non-empty list of widths (got {arch!r})")
    act = getattr(kwargs.get("activation_fn"), "__name__", "Tanh")
    if act not in ACTIVATIONS:
        raise UserError(f"activation_fn {act} has no RLlib name ({', '.join(ACTIVATIONS)})")
    if norm is not None and float(norm.get("clip_obs", CLIP_OBS)) != CLIP_OBS:
        raise UserError(f"RLlib's observation filter clips at {CLIP_OBS} (normalize.clip_obs)")
    n_envs, n_steps = int(_number(hp, "n_envs")), int(_number(hp, "n_steps"))
    grad = _number(hp, "max_grad_norm")
    return PPOSettings(
        hidden=tuple(arch), activation=ACTIVATIONS[act],
        log_std_init=float(kwargs.get("log_std_init", SB3_DEFAULTS["log_std_init"])),
        gamma=_number(hp, "gamma"), lambda_=_number(hp, "gae_lambda"),
        lr=_number(hp, "learning_rate"), clip_param=_number(hp, "clip_range"),
        num_epochs=int(_number(hp, "n_epochs")), minibatch_size=int(_number(hp, "batch_size")),
        train_batch_size=n_envs * n_steps, entropy_coeff=_number(hp, "ent_coef"),
        vf_loss_coeff=_number(hp, "vf_coef"), grad_clip=grad if grad > 0 else None,
        norm_obs=norm is not None and bool(norm.get("norm_obs", True)),
    )


def exported_normalize(settings: PPOSettings, epsilon: float) -> dict[str, Any] | bool:
    """The ``normalize`` entry of the exported run: observations as RLlib's filter normalised
    them (``epsilon``: see :mod:`agents.rllib.export`), rewards not normalised."""
    if not settings.norm_obs:
        return False
    return {"norm_obs": True, "norm_reward": False, "clip_obs": CLIP_OBS, "epsilon": epsilon}
