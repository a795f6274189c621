"""pegtwin from Python: trials, campaigns, registration and manifolds of the Rust library.

The Rust library does the work (``pegtwin._pegtwin`` is a thin binding); this module turns its
records into Python dicts, numpy arrays and pandas DataFrames. Units are SI (m, rad, N, s)
except where a name says mm or deg, as on the command line. Every bad argument raises
``ValueError`` with the message the command line prints; the GIL is released while the
simulation runs, so other Python threads go on.

The Gymnasium environment is ``pegtwin.gym.PegInHoleEnv``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Sequence, Union

import numpy as np

from . import _pegtwin
from . import gym  # noqa: F401  (pegtwin.gym.PegInHoleEnv; registers "pegtwin/PegInHole-v0")

__version__ = _pegtwin.__version__

PathLike = Union[str, "os.PathLike[str]"]

__all__ = [
    "Manifold",
    "campaign",
    "check",
    "evaluate",
    "gym",
    "load_summary",
    "load_trials",
    "merge",
    "register",
    "rerun",
    "trial",
    "tune",
]


def _path(p: Optional[PathLike]) -> Optional[str]:
    return None if p is None else os.fspath(p)


def trial(
    geometry: Optional[str] = None,
    clearance_mm: Optional[float] = None,
    seed: int = 1,
    t_obs_s: Optional[float] = None,
    method: str = "manifold",
    start: str = "partial",
    offset_mm: Optional[float] = None,
    offset_deg: Optional[float] = None,
    manifold: Optional[PathLike] = None,
    cache_dir: Optional[PathLike] = None,
    assembly: Optional[PathLike] = None,
    profile: str = "real",
    sampler: str = "robot",
) -> Dict[str, Any]:
    """Runs one trial of the paper's experiment (paper V-A) and returns its record.

    The record is the one ``pegtwin trial --json`` prints for the same arguments (outcome,
    estimate errors, final depth, forces, phase times). Arguments left out take the command
    line's defaults (t_obs 10 s, offsets U(-5, 5) mm and deg).

    Args:
        geometry: a built-in part pair: ``cross``, ``extrusion``, ``plug3``, ``key``, ``gear``.
        clearance_mm: diametral clearance of the built-in, mm (0.01-5).
        seed: the trial seed; it draws the hole offset and seeds every noise source.
        t_obs_s: observation time, s.
        method: ``manifold`` (the paper's method), ``direct`` (its baseline), ``adaptive``
            (the paper's method observing until its estimate is certain enough, at most
            ``t_obs``; the record's ``observation_s`` says how long and ``observation_stop``
            why: ``certain``, ``out_of_reach``, ``budget`` or ``fault``) or ``active`` (adaptive,
            widening the motion on the axes it knows least; ``widened`` counts what its checks
            widened: ``lateral``, ``tilt``, ``yaw``).
        start: ``partial`` (partially inserted, the paper's set-up) or ``above`` (search first).
        offset_mm: half-range of the hole's position offset, mm.
        offset_deg: half-range of the hole's orientation offset, deg.
        manifold: a reference manifold file; by default the cached one, built when missing
            (a minute or more per pair on two cores).
        cache_dir: folder of cached manifolds (default ``$XDG_CACHE_HOME/pegtwin`` or
            ``~/.cache/pegtwin``).
        assembly: an assembly file (your own peg and hole, README "Your own parts and robot")
            instead of ``geometry`` and ``clearance_mm``; its clearance is measured.
        profile: ``real`` (the real cell's imperfections drawn from the seed; the record's
            ``real_cell`` holds the draw) or ``ideal`` (every imperfection off).
        sampler: how the cached reference manifold is made when ``manifold`` is not given:
            ``robot`` (the arm probes the hole in simulation, paper IV-B) or ``geometric``
            (the poses where the parts touch, from their shapes alone).

    Raises:
        ValueError: an argument is out of range or unknown, or a file is unreadable.
    """
    text = _pegtwin.trial_json(
        geometry,
        None if clearance_mm is None else float(clearance_mm),
        int(seed),
        method,
        start,
        t_obs_s=t_obs_s,
        offset_mm=offset_mm,
        offset_deg=offset_deg,
        manifold=_path(manifold),
        cache_dir=_path(cache_dir),
        assembly=_path(assembly),
        profile=profile,
        sampler=sampler,
    )
    return json.loads(text)


def campaign(
    scenario: PathLike,
    out: PathLike,
    threads: Optional[int] = None,
    shard: Optional[str] = None,
    resume: bool = False,
    cache_dir: Optional[PathLike] = None,
    replays: str = "failures",
    progress: Optional[Callable[[int, int], None]] = None,
) -> str:
    """Runs a campaign from a scenario file into ``out`` and writes its report.

    The same as ``pegtwin campaign SCENARIO --out OUT``: trials in parallel on ``threads``
    workers (results do not depend on it), ``trials.jsonl``, ``summary.json``, ``report.html``.

    Args:
        progress: called as ``progress(done, total)`` when the trials start and after each
            one (from worker threads, holding the GIL). For tqdm::

                bar = tqdm.tqdm()
                def show(done, total):
                    bar.total = total
                    bar.n = done
                    bar.refresh()

            An exception raised by it stops the campaign and is raised here.

    Ctrl-C stops the campaign cleanly: the trials running finish, everything finished is kept,
    ``KeyboardInterrupt`` is raised, and ``campaign(..., resume=True)`` completes the folder.

    Returns:
        ``out``, as a string.
    """
    return _pegtwin.campaign(
        _path(scenario),
        _path(out),
        threads=threads,
        shard=shard,
        resume=resume,
        cache_dir=_path(cache_dir),
        replays=replays,
        progress=progress,
    )


def merge(
    dirs: "Sequence[PathLike]",
    out: PathLike,
    resume: bool = False,
    cache_dir: Optional[PathLike] = None,
) -> str:
    """Joins the result folders of a campaign's shards into ``out``, with the report (``pegtwin
    merge``): the folder an unsharded run writes, its ``trials.jsonl`` byte for byte.

    Returns:
        ``out``, as a string.
    """
    return _pegtwin.merge([_path(d) for d in dirs], _path(out), resume=resume,
                          cache_dir=_path(cache_dir))


def check(
    dir: PathLike,
    baseline: Optional[PathLike] = None,
    write_baseline: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """The regression gate (``pegtwin check``) on a finished campaign folder.

    With ``baseline``: ``{"passed": bool, "findings": [...]}``, one finding per compared
    quantity (``cell``, ``quantity``, ``baseline``, ``now``, ``limit``, ``failed``). With
    ``write_baseline``: the run's summary is written there as a baseline; returns ``{"written":
    path, "cells": n}``.
    """
    return json.loads(_pegtwin.check_json(_path(dir), baseline=_path(baseline),
                                          write_baseline=_path(write_baseline)))


def rerun(
    campaign: PathLike, cell: int, trial: int, cache_dir: Optional[PathLike] = None
) -> Dict[str, Any]:
    """One trial of a campaign again, on its own (``pegtwin rerun --json``): its record, the
    campaign's bit for bit. ``campaign``: the scenario file or the results folder; ``cell`` and
    ``trial`` numbered from 0 as in ``trials.jsonl``."""
    return json.loads(_pegtwin.rerun_json(_path(campaign), cell, trial,
                                          cache_dir=_path(cache_dir)))


def tune(
    scenario: PathLike,
    out: PathLike,
    candidates: Optional[int] = None,
    first_trials: Optional[int] = None,
    seed: Optional[int] = None,
    target: str = "gains",
    threads: Optional[int] = None,
    cache_dir: Optional[PathLike] = None,
    resume: bool = False,
) -> "pandas.DataFrame":  # noqa: F821
    """Gain tuning (``pegtwin tune``) into ``out``: a Latin hypercube and successive halving
    (docs/campaigns.md). ``resume=True`` goes on with a search killed in ``out``, to the
    uninterrupted one's result. Returns ``tune.csv`` as a DataFrame; the winner's scenario
    snippet is in ``attrs["snippet"]``."""
    import pandas as pd

    done = json.loads(_pegtwin.tune_json(
        _path(scenario), _path(out), candidates=candidates, first_trials=first_trials,
        seed=seed, target=target, threads=threads, cache_dir=_path(cache_dir), resume=resume,
    ))
    frame = pd.read_csv(done["csv"])
    frame.attrs["snippet"] = done["snippet"]
    return frame


def evaluate(
    scenario: PathLike,
    overrides: str = "",
    trials: "range" = range(0, 1),
    threads: Optional[int] = None,
    cache_dir: Optional[PathLike] = None,
) -> "pandas.DataFrame":  # noqa: F821
    """Runs trials ``trials`` (indices from 0, as in ``trials.jsonl``) of every cell of a
    scenario with the TOML ``overrides`` laid over it, and returns their records as
    ``load_trials`` does.

    ``overrides`` is scenario text whose tables are merged into the file's key by key, e.g.
    ``"[gains.insert]\nstiffness = [1500, 1500, 2000, 50, 50, 50]"``. Every call meets the
    same trial seeds (each record is the campaign's record of that trial), so candidates of an
    outer search such as Optuna's are compared on the same hole offsets
    (``python/examples/optuna_gains.py``).
    """
    import pandas as pd

    if not isinstance(trials, range) or trials.step != 1:
        raise ValueError(f"trials {trials!r}: expected a range of trial indices with step 1")
    text = _pegtwin.evaluate_json(_path(scenario), overrides, trials.start, trials.stop,
                                  threads=threads, cache_dir=_path(cache_dir))
    return pd.DataFrame([_flat_record(json.loads(line)) for line in text.splitlines()])


def _flat_record(record: Dict[str, Any]) -> Dict[str, Any]:
    """One trials.jsonl line as one DataFrame row: nested fields become prefixed columns."""
    result = dict(record)
    row: Dict[str, Any] = {"cell": result.pop("cell"), "trial": result.pop("trial")}
    offset = result.pop("offset")
    for name, v in zip(["x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg"], offset):
        row[f"offset_{name}"] = v
    errors = result.pop("errors") or {}
    for name in ["x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg"]:
        row[f"error_{name}"] = errors.get(name, np.nan)
    estimate = result.pop("estimate")
    std = result.pop("estimate_std", None)
    for i, name in enumerate(["x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"]):
        row[f"estimate_{name}"] = np.nan if estimate is None else estimate[i]
        row[f"estimate_std_{name}"] = np.nan if std is None else std[i]
    fault = result.pop("fault")
    row["fault_reason"] = None if fault is None else fault["reason"]
    row["fault_time_s"] = np.nan if fault is None else fault["time_s"]
    energy = None if fault is None else fault.get("energy")
    row["fault_source"] = None if energy is None else energy["source"]
    for name, v in result.pop("times").items():
        row[f"time_{name}"] = v
    for name, v in result.items():
        _flatten_into(row, name, v)
    if row["final_depth_mm"] is None:
        row["final_depth_mm"] = np.nan
    return row


def _flatten_into(row: Dict[str, Any], name: str, value: Any) -> None:
    """``value`` under the column ``name``: a dict's fields as ``name_field``, recursively."""
    if isinstance(value, dict):
        for key, v in value.items():
            _flatten_into(row, f"{name}_{key}", v)
    else:
        row[name] = value


def load_trials(dir: PathLike) -> "pandas.DataFrame":  # noqa: F821
    """The trials of a campaign folder (or of the Parquet file ``pegtwin export`` wrote from
    one: the same columns, read with pyarrow), one row per trial.

    Columns: ``cell``, ``trial``, ``seed``, ``geometry``, ``clearance_mm``, ``method``,
    ``start``, ``t_obs_s``, ``outcome``, ``success``, ``final_depth_mm``, ``peak_fz_n``,
    ``mean_fz_n``, ``contact_observations``, ``observations_used``, the hole offset
    ``offset_x_mm`` ... ``offset_yaw_deg``, the estimate's errors ``error_x_mm`` ...
    ``error_yaw_deg`` (NaN for ``direct``), the estimate ``estimate_x_m`` ... ``estimate_yaw_rad``,
    its standard deviations ``estimate_std_x_m`` ... ``estimate_std_yaw_rad`` and covariance
    ``estimate_covariance`` (6 rows of 6, m and rad, in the estimated hole frame; None for ``direct``),
    ``fault_reason``, ``fault_time_s`` and ``fault_source`` (who put in the energy that ended a
    ``sim_fault``: ``drives``, the commanded motion; ``contacts`` or ``integration``, the
    physics), ``stopped``, the phase times ``time_search_s`` ...
    ``time_insert_s``, ``insert_fz_n`` (the insertion's |Fz| profile, a list per row), and
    ``insert_end`` (what ended the insertion: ``seat``, ``jam``, ``travel`` or ``limit``);
    for the adaptive and active methods ``observation_s``, ``observation_stop``, ``check_s`` and
    ``check_std`` (each check's time and the standard deviations then, lists per row); the
    real cell's draw (``real_cell_contact_friction``, ...) and the print's (``print_clearance_m``,
    ...), nested objects flattened with ``_``.
    """
    import pandas as pd

    if Path(dir).is_file():
        return _load_parquet(Path(dir))
    path = Path(dir) / "trials.jsonl"
    if not path.is_file():
        raise ValueError(f"{path}: no trials.jsonl (is {dir} a campaign folder?)")
    rows = []
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                rows.append(_flat_record(json.loads(line)))
            except (json.JSONDecodeError, KeyError, TypeError) as e:
                raise ValueError(f"{path}: line {n}: not a trial record ({e})") from None
    return pd.DataFrame(rows)


def _load_parquet(path: Path) -> "pandas.DataFrame":  # noqa: F821
    """A table ``pegtwin export --parquet`` wrote."""
    import pandas as pd

    try:
        import pyarrow  # noqa: F401
    except ImportError:
        raise ImportError(
            f"{path}: reading Parquet needs pyarrow: pip install pyarrow"
        ) from None
    with open(path, "rb") as f:
        if f.read(4) != b"PAR1":
            raise ValueError(
                f"{path}: not a Parquet file (expected a campaign folder, or the file "
                "`pegtwin export --parquet` wrote)"
            )
    return pd.read_parquet(path)


def load_summary(dir: PathLike) -> "pandas.DataFrame":  # noqa: F821
    """The per-cell summary of a finished campaign (``summary.json``), one row per cell.

    Columns are the summary's fields (geometry, clearance, method, t_obs, trials, successes,
    success rate and its Wilson interval, errors, forces); nested ones are flattened with ``_``.
    The whole file is in ``DataFrame.attrs["summary"]``.
    """
    import pandas as pd

    path = Path(dir) / "summary.json"
    if not path.is_file():
        raise ValueError(f"{path}: no summary.json (is {dir} a finished campaign folder?)")
    with open(path, encoding="utf-8") as f:
        summary = json.load(f)
    frame = pd.json_normalize(summary["cells"], sep="_")
    frame.attrs["summary"] = summary
    return frame


class Manifold:
    """A reference contact manifold (paper IV-B): contact poses ``hole_T_peg`` and normals.

    ``points`` and ``normals`` are (N, 6) float64 arrays: x, y, z in m and roll, pitch, yaw
    in rad (R = Rz(yaw) Ry(pitch) Rx(roll)); normals in the manifold's scaled 6-D metric.
    """

    def __init__(self, inner: "_pegtwin.ManifoldFile") -> None:
        self._inner = inner

    @classmethod
    def load(cls, path: PathLike) -> "Manifold":
        """Loads a manifold file written by ``pegtwin manifold build|import|synth``."""
        return cls(_pegtwin.ManifoldFile.load(os.fspath(path)))

    @property
    def points(self) -> np.ndarray:
        return self._inner.points

    @property
    def normals(self) -> np.ndarray:
        return self._inner.normals

    @property
    def meta(self) -> Dict[str, Any]:
        """Geometry, clearance (m), units, metric, neighbours, source and seed."""
        return json.loads(self._inner.meta_json())

    def __len__(self) -> int:
        return len(self._inner)

    def __repr__(self) -> str:
        meta = self.meta
        return f"Manifold({meta['geometry']!r}, {len(self)} poses)"


def register(
    manifold: Union[Manifold, PathLike],
    observations: "np.typing.ArrayLike",
    init: "np.typing.ArrayLike",
    solver: Optional[str] = None,
    iterations: Optional[int] = None,
    restarts: Optional[int] = None,
    seed: Optional[int] = None,
    normal_k: Optional[int] = None,
) -> Dict[str, Any]:
    """Estimates the hole pose from contact observations (paper IV-D, Algorithm 1).

    Args:
        manifold: a ``Manifold`` or the path of a manifold file.
        observations: (N, 6) contact poses ``base_T_peg`` (m, rad).
        init: the initial hole estimate ``base_T_hole``, 6 values (m, rad).
        solver: ``least-squares`` (default) or ``paper`` (Algorithm 1's update).
        iterations, restarts, seed, normal_k: the registration's settings (defaults as
            ``pegtwin register``).

    Returns:
        The registration (``pegtwin register --json`` prints it under ``result``): ``estimate``
        (the hole pose ``base_T_hole`` as a numpy array, m and rad), ``solver``, ``restarts``
        (each with its initial and final pose, iterations, residual and whether it was
        rejected), ``kept``, ``estimate_std`` (the estimate's standard deviation per axis, m and
        rad, in the estimated hole frame, as a numpy array), ``covariance`` (its 6 x 6
        covariance, a numpy array) and ``time`` (wall seconds per stage).
    """
    if not isinstance(manifold, Manifold):
        manifold = Manifold.load(manifold)
    obs = np.ascontiguousarray(np.asarray(observations, dtype=np.float64))
    if obs.ndim != 2:
        raise ValueError(
            f"observations with {obs.ndim} dimensions: expected (N, 6) rows of x, y, z (m), "
            "roll, pitch, yaw (rad)"
        )
    start = np.ascontiguousarray(np.asarray(init, dtype=np.float64).reshape(-1))
    text = _pegtwin.register_json(
        manifold._inner,
        obs,
        start,
        solver=solver,
        iterations=iterations,
        restarts=restarts,
        seed=seed,
        normal_k=normal_k,
    )
    result = json.loads(text)
    for key in ["estimate", "estimate_std", "covariance"]:
        result[key] = np.asarray(result[key], dtype=np.float64)
    return result
