"""Shared fixtures: the command-line binary (the reference the package must agree with), a
small reference manifold and a small campaign scenario, built once per test session."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `pegtwin` binary: $PEGTWIN_BIN, or the checkout's release build."""
    path = Path(os.environ.get("PEGTWIN_BIN", REPO / "target" / "release" / "pegtwin"))
    if not path.is_file():
        pytest.fail(f"no pegtwin binary at {path}: run `cargo build --release` or set PEGTWIN_BIN")
    return path


def run_cli(cli: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(cli), *args], capture_output=True, text=True)


@pytest.fixture(scope="session")
def small_manifold(cli: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 400-pose reference manifold of the cross at 0.5 mm (two 3 s sampling episodes)."""
    out = tmp_path_factory.mktemp("manifold") / "cross.manifold"
    o = run_cli(
        cli, "manifold", "build", "--geometry", "cross", "--clearance-mm", "0.5",
        "--episodes", "2", "--episode-s", "3", "--points", "400", "--seed", "4",
        "--quiet", "--out", str(out),
    )
    assert o.returncode == 0, o.stderr
    return out


@pytest.fixture(scope="session")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four short trials: the manifold method and the direct baseline, 2 each, t_obs 2 s, with
    a reduced manifold (built into the test's own cache)."""
    path = tmp_path_factory.mktemp("scenario") / "tiny.toml"
    path.write_text(
        'name = "tiny"\nseed = 7\ntrials = 2\ngeometries = ["cross"]\nclearances_mm = [0.5]\n'
        't_obs_s = [2.0]\nmethods = ["manifold", "direct"]\ndirect_t_obs_s = 2.0\n\n'
        "[manifold]\npoints = 1000\nepisodes = 2\nepisode_s = 3.0\nseed = 4\n"
    )
    return path


@pytest.fixture(scope="session")
def cross_assembly(cli: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An assembly file of the cross's exported convex parts at 0.5 mm (the built-ins' peg mass)."""
    folder = tmp_path_factory.mktemp("assembly")
    o = run_cli(
        cli, "geometry", "export", "cross", "--clearance-mm", "0.5", "--out",
        str(folder / "cad"), "--convex-parts",
    )
    assert o.returncode == 0, o.stderr
    path = folder / "mine.toml"
    path.write_text(
        'name = "mine"\n[peg]\nmesh = "cad/peg_parts"\nunits = "mm"\nmass_kg = 0.3\n'
        '[hole]\nmesh = "cad/hole_parts"\nunits = "mm"\n'
    )
    return path
