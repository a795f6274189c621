"""The Gymnasium environment: the checker, determinism, the trial's set-up, errors."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import pegtwin
from pegtwin.gym import PegInHoleEnv


def test_the_gymnasium_checker_passes() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no render modes: intended
        check_env(PegInHoleEnv())
        check_env(PegInHoleEnv(variable_stiffness=True, control_hz=50))


def test_the_environment_is_registered_and_vectorises() -> None:
    import gymnasium

    assert pegtwin.gym.PegInHoleEnv is PegInHoleEnv  # `import pegtwin` is enough
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gymnasium.make("pegtwin/PegInHole-v0", geometry="cross", clearance_mm=0.5)
        check_env(env.unwrapped)
    assert np.all(np.isfinite(env.observation_space.low))
    assert np.all(np.isfinite(env.observation_space.high))
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs) and info["observation_clipped"] is False
    envs = gymnasium.make_vec("pegtwin/PegInHole-v0", num_envs=2, vectorization_mode="sync")
    obs, _ = envs.reset(seed=[1, 2])
    assert obs.shape == (2, 12)
    obs, reward, terminated, truncated, _ = envs.step(envs.action_space.sample())
    assert obs.shape == (2, 12) and reward.shape == (2,)
    envs.close()


def rollout(env: PegInHoleEnv, seed: int, steps: int) -> list:
    obs, info = env.reset(seed=seed)
    actions = np.random.default_rng(seed).uniform(-1, 1, size=(steps, env.action_space.shape[0]))
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out += [obs, reward, info["true_wrench"], info["depth_m"]]
    return out


def test_episodes_are_deterministic_per_seed() -> None:
    a, b = rollout(PegInHoleEnv(), 11, 30), rollout(PegInHoleEnv(), 11, 30)
    c = rollout(PegInHoleEnv(), 12, 30)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])


def test_a_reset_sets_up_the_trial_of_that_seed() -> None:
    env = PegInHoleEnv()
    obs, info = env.reset(options={"trial_seed": 3})
    record = pegtwin.trial("cross", 0.5, seed=3, method="direct", t_obs_s=1)
    offset = np.asarray(info["hole_offset"])
    in_mm_deg = np.concatenate([offset[:3] * 1e3, np.degrees(offset[3:])])
    assert np.allclose(in_mm_deg, record["offset"], atol=1e-9)
    assert obs.shape == (12,) and obs.dtype == np.float32
    assert info["depth_m"] == pytest.approx(3e-3, abs=1e-5)  # the paper's partial insertion


def assert_pushing_down_inserts(env: PegInHoleEnv) -> None:
    """From the partial insertion, pushing straight down inserts without a fault."""
    _, info = env.reset(seed=0)
    assert info["depth_m"] == pytest.approx(3e-3, abs=1e-5)
    for _ in range(60):
        _, _, terminated, truncated, info = env.step(np.array([0, 0, -1, 0, 0, 0.0]))
        if terminated or truncated:
            break
    assert info["success"] and info["sim_fault"] is None


def test_an_assembly_file_is_an_environment_too(cross_assembly: Path) -> None:
    assembly = cross_assembly
    env = PegInHoleEnv(assembly=assembly, offset_mm=0, offset_deg=0)
    assert_pushing_down_inserts(env)


def test_the_six_joint_ur5e_of_an_assembly_drives_the_environment(tmp_path: Path) -> None:
    assembly = tmp_path / "ur.toml"
    assembly.write_text(
        'name = "cross-ur5e"\nclearance_mm = 0.5\n[peg]\nbuiltin = "cross"\n'
        '[hole]\nbuiltin = "cross"\n[robot]\nbuiltin = "ur5e"\n'
    )
    env = PegInHoleEnv(assembly=assembly, offset_mm=0, offset_deg=0)
    assert_pushing_down_inserts(env)


def test_pushing_down_inserts_and_the_truth_is_in_info() -> None:
    env = PegInHoleEnv(offset_mm=0, offset_deg=0)
    env.reset(seed=0)
    total, info = 0.0, {}
    for _ in range(60):
        _, reward, terminated, truncated, info = env.step(np.array([0, 0, -1, 0, 0, 0.0]))
        total += reward
        if terminated or truncated:
            break
    assert info["success"] and terminated and info["sim_fault"] is None
    assert info["depth_m"] > 0.025 and total > 20
    assert 0 <= info["penetration_m"] < 0.05e-3
    assert len(info["true_wrench"]) == 6


def test_bad_arguments_raise_value_errors() -> None:
    with pytest.raises(ValueError, match="clearance 9 mm"):
        PegInHoleEnv(clearance_mm=9)
    with pytest.raises(ValueError, match="control_hz 7"):
        PegInHoleEnv(control_hz=7)
    env = PegInHoleEnv()
    with pytest.raises(ValueError, match="step before reset"):
        env.step(np.zeros(6))
    env.reset(seed=1)
    with pytest.raises(ValueError, match="action of length 3"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="action value NaN"):
        env.step(np.array([0, 0, np.nan, 0, 0, 0]))
