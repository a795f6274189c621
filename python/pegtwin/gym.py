"""``PegInHoleEnv``: the pegtwin cell as a Gymnasium environment.

A reset sets up one trial of the paper's experiment (V-A): the hole is offset from its nominal
pose by U(-5, 5) mm and deg (drawn from the episode's seed exactly as ``pegtwin.trial`` draws
it for that seed), and the peg on the KUKA LBR iiwa 14's flange starts partially inserted in
the true hole (``start="partial"``, 3 mm deep) or above the nominal mouth (``start="above"``).

A step moves the Cartesian impedance target (the robot's command, as in Sunrise's smart servo)
and runs the physics underneath at 1 kHz for one control period (20 Hz by default: 50 physics
steps of 1 ms, each with the impedance law, the joint torques and rapier's contacts).

Action, ``Box(-1, 1, (6,))`` (``(8,)`` with ``variable_stiffness=True``), clipped to [-1, 1]:
    0-2: target translation along the nominal hole frame's x, y, z, times ``max_step_mm``
         (1 mm) per step;
    3-5: target rotation about the TCP's x, y, z, times ``max_step_deg`` (0.5 deg) per step;
    6-7: translational and rotational stiffness of every axis, -1 to 1 mapped linearly onto
         Sunrise's 0-5000 N/m and 0-300 N m/rad (default: the insertion's 1500/2000 N/m and
         50 N m/rad).

Observation, ``Box(low, high, (12,), float32)``, what the real robot measures:
    0-5:  TCP pose in the nominal hole frame from the joint encoders: x, y, z (m, within
          +-2 m: an arm's reach around the hole), roll, yaw (rad, +-pi), pitch (rad, +-pi/2);
          the tip is at z < 0 once inside the hole;
    6-11: the external wrench estimated from the joint torque sensors (with their noise), base
          frame: fx, fy, fz (N, within +-1000 N), tx, ty, tz (N m, within +-320 N m, the iiwa
          14's largest joint torque).
    A value beyond its bound is clipped to it and ``info["observation_clipped"]`` is True (the
    unclipped physics goes on; ``info["true_wrench"]`` is never clipped).

Reward per step: +1 per mm of depth gained in the true hole, -0.01 per N of estimated force
beyond 10 N, +10 on success. ``terminated``: success (the tip within 2 mm of the cavity floor,
the paper's criterion) or a physics fault (``info["sim_fault"]`` says why). ``truncated``: the
episode's time (10 s by default) is up. ``info``: ``time_s``, ``depth_m`` (below the true
mouth), ``true_wrench`` (from the physics), ``penetration_m`` (exact, peg into hole),
``contact``, ``success``, ``sim_fault``, ``hole_offset`` (m, rad).

Seeding is deterministic: ``reset(seed=s)`` gives the same episode every time, whatever the
machine; ``reset()`` draws the next trial seed from the environment's own generator.
"""

from __future__ import annotations

import os
from typing import Any, Dict, Optional, Tuple, Union

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from . import _pegtwin

__all__ = ["PegInHoleEnv", "ENV_ID", "OBSERVATION_LOW", "OBSERVATION_HIGH"]

#: The environment's Gymnasium id: ``gymnasium.make("pegtwin/PegInHole-v0", **kwargs)``.
ENV_ID = "pegtwin/PegInHole-v0"

#: The observation's bounds (module docs): pose in m and rad, wrench in N and N m.
OBSERVATION_HIGH = np.array(
    [2.0, 2.0, 2.0, np.pi, np.pi / 2, np.pi, 1000.0, 1000.0, 1000.0, 320.0, 320.0, 320.0],
    dtype=np.float32,
)
OBSERVATION_LOW = -OBSERVATION_HIGH


class PegInHoleEnv(gym.Env):
    """The iiwa 14 inserting a peg under Cartesian impedance, step by step (module docs)."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        geometry: str = "cross",
        clearance_mm: float = 0.5,
        start: str = "partial",
        control_hz: Optional[float] = None,
        episode_s: Optional[float] = None,
        offset_mm: Optional[float] = None,
        offset_deg: Optional[float] = None,
        max_step_mm: Optional[float] = None,
        max_step_deg: Optional[float] = None,
        variable_stiffness: bool = False,
        assembly: Optional[Union[str, os.PathLike]] = None,
        profile: str = "real",
    ) -> None:
        """Args: see the module docs; values left out take the defaults named there.
        ``assembly``: an assembly file (your own peg and hole) instead of ``geometry`` and
        ``clearance_mm``. ``profile``: ``real`` (each episode's cell draws the real cell's
        imperfections from its seed) or ``ideal``.

        Raises:
            ValueError: an argument is out of range or unknown (the command line's message).
        """
        super().__init__()
        mine = assembly is not None
        self._env = _pegtwin.Env(
            None if mine else geometry,
            None if mine else float(clearance_mm),
            start=start,
            control_hz=control_hz,
            episode_s=episode_s,
            offset_mm=offset_mm,
            offset_deg=offset_deg,
            max_step_mm=max_step_mm,
            max_step_deg=max_step_deg,
            variable_stiffness=variable_stiffness,
            assembly=os.fspath(assembly) if mine else None,
            profile=profile,
        )
        self.control_hz: float = self._env.control_hz
        self.episode_s: float = self._env.episode_s
        n = self._env.action_len
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        self.observation_space = spaces.Box(
            OBSERVATION_LOW, OBSERVATION_HIGH, shape=(12,), dtype=np.float32
        )

    def reset(
        self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None
    ) -> Tuple[np.ndarray, Dict[str, Any]]:
        """Starts an episode. ``seed`` seeds the environment's generator, which draws the
        trial seed (``options={"trial_seed": s}`` runs trial ``s`` itself, as
        ``pegtwin.trial(seed=s)`` sets it up)."""
        super().reset(seed=seed)
        if options and "trial_seed" in options:
            trial_seed = int(options["trial_seed"])
        else:
            trial_seed = int(self.np_random.integers(0, 2**63 - 1))
        obs, info = self._env.reset(trial_seed)
        info["trial_seed"] = trial_seed
        return _bounded(obs, info), info

    def step(
        self, action: np.ndarray
    ) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]:
        a = np.ascontiguousarray(np.asarray(action, dtype=np.float64).reshape(-1))
        obs, reward, terminated, truncated, info = self._env.step(a)
        return _bounded(obs, info), float(reward), terminated, truncated, info


def _bounded(obs: np.ndarray, info: Dict[str, Any]) -> np.ndarray:
    """The observation as float32 within the space's bounds; says in ``info`` if it was not."""
    out = obs.astype(np.float32)
    clipped = bool(np.any(out < OBSERVATION_LOW) or np.any(out > OBSERVATION_HIGH))
    info["observation_clipped"] = clipped
    return np.clip(out, OBSERVATION_LOW, OBSERVATION_HIGH) if clipped else out


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="pegtwin.gym:PegInHoleEnv")
