"""The native-vector-env PPO entries (agents/configs/ppo_native.yml)."""

from __future__ import annotations

from agents.runs.hyperparams import CONFIG_DIR, algo_kwargs, load_hyperparams

CONF = CONFIG_DIR / "ppo_native.yml"


def test_reorient_native_entry_loads_and_keeps_the_ppo_yml_task_settings():
    native = load_hyperparams("ppo", "SoftHandReorient-v0", str(CONF))
    dummy = load_hyperparams("ppo", "SoftHandReorient-v0")
    assert native["vec_env"] == "native" and "vec_env" not in dummy
    assert native["env_kwargs"] == dummy["env_kwargs"]
    assert native["policy_kwargs"] == dummy["policy_kwargs"]
    assert native["normalize"] == dummy["normalize"]
    assert native["n_envs"] * native["n_steps"] == 8192
    kwargs = algo_kwargs("ppo", native)  # every algorithm key in range
    assert kwargs["batch_size"] == 1024 and kwargs["n_epochs"] == 5


def test_v1_entries_are_the_v0_entries():
    for task in ("Reorient", "ReorientRandom", "PoseRandom"):
        assert (load_hyperparams("ppo", f"SoftHand{task}-v1", str(CONF))
                == load_hyperparams("ppo", f"SoftHand{task}-v0", str(CONF)))
    # the Pose-v1 student reads its fingertips like the Random tier's
    assert (load_hyperparams("ppo", "SoftHandPose-v1", str(CONF))
            == load_hyperparams("ppo", "SoftHandPoseRandom-v0", str(CONF)))
    translate = load_hyperparams("ppo", "SoftHandTranslate-v1", str(CONF))
    shipped = load_hyperparams("ppo", "SoftHandTranslate-v0")  # ppo.yml, the v0 model's entry
    assert translate["env_kwargs"] == shipped["env_kwargs"]
    assert translate["n_timesteps"] == shipped["n_timesteps"] == 2_000_000
    assert translate["vec_env"] == "native"
    assert translate["policy_kwargs"] == shipped["policy_kwargs"]
    teacher = CONFIG_DIR / "teacher.yml"
    assert (load_hyperparams("ppo", "SoftHandPose-v1", str(teacher))
            == load_hyperparams("ppo", "SoftHandPose-v0", str(teacher)))
