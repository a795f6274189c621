"""Type stubs of the Rust binding (``pegtwin._pegtwin``); use the ``pegtwin`` module's API."""

from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

__version__: str

def trial_json(
    geometry: Optional[str],
    clearance_mm: Optional[float],
    seed: int,
    method: str,
    start: str,
    t_obs_s: Optional[float] = None,
    offset_mm: Optional[float] = None,
    offset_deg: Optional[float] = None,
    manifold: Optional[str] = None,
    cache_dir: Optional[str] = None,
    assembly: Optional[str] = None,
    profile: str = "real",
    sampler: str = "robot",
) -> str: ...
def campaign(
    scenario: str,
    out: str,
    threads: Optional[int] = None,
    shard: Optional[str] = None,
    resume: bool = False,
    cache_dir: Optional[str] = None,
    replays: str = "failures",
    progress: Optional[Callable[[int, int], None]] = None,
) -> str: ...
def register_json(
    manifold: ManifoldFile,
    observations: np.ndarray,
    init: np.ndarray,
    solver: Optional[str] = None,
    iterations: Optional[int] = None,
    restarts: Optional[int] = None,
    seed: Optional[int] = None,
    normal_k: Optional[int] = None,
) -> str: ...
def merge(
    dirs: List[str], out: str, resume: bool = False, cache_dir: Optional[str] = None
) -> str: ...
def check_json(
    dir: str, baseline: Optional[str] = None, write_baseline: Optional[str] = None
) -> str: ...
def rerun_json(campaign: str, cell: int, trial: int, cache_dir: Optional[str] = None) -> str: ...
def tune_json(
    scenario: str,
    out: str,
    candidates: Optional[int] = None,
    first_trials: Optional[int] = None,
    seed: Optional[int] = None,
    target: str = "gains",
    threads: Optional[int] = None,
    cache_dir: Optional[str] = None,
    resume: bool = False,
) -> str: ...
def evaluate_json(
    scenario: str,
    overrides: str,
    start: int,
    stop: int,
    threads: Optional[int] = None,
    cache_dir: Optional[str] = None,
) -> str: ...

class ManifoldFile:
    @staticmethod
    def load(path: str) -> ManifoldFile: ...
    @property
    def points(self) -> np.ndarray: ...
    @property
    def normals(self) -> np.ndarray: ...
    def meta_json(self) -> str: ...
    def __len__(self) -> int: ...

class Env:
    def __init__(
        self,
        geometry: Optional[str],
        clearance_mm: Optional[float],
        start: str = "partial",
        control_hz: Optional[float] = None,
        episode_s: Optional[float] = None,
        offset_mm: Optional[float] = None,
        offset_deg: Optional[float] = None,
        max_step_mm: Optional[float] = None,
        max_step_deg: Optional[float] = None,
        variable_stiffness: bool = False,
        assembly: Optional[str] = None,
        profile: str = "real",
    ) -> None: ...
    @property
    def action_len(self) -> int: ...
    @property
    def control_hz(self) -> float: ...
    @property
    def episode_s(self) -> float: ...
    def reset(self, seed: int) -> Tuple[np.ndarray, Dict[str, Any]]: ...
    def step(
        self, action: np.ndarray
    ) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]: ...
