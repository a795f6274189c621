"""`pegtwin assembly decompose` and `decompose = "coacd"`: filleted pins, a rounded cross and a
slotted circle (curved and slanted faces: neither convex nor a stack of extrusions), go from one
STL through CoACD to a trial, their parts within a quarter of the clearance of their surface; a
missing CoACD or Python is refused by name."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import pins

CLEARANCE_MM = 1.0


def run(cli: Path, *args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([str(cli), *args], capture_output=True, text=True,
                          env={**os.environ, **(env or {})})


def pair(folder: Path, shape: str) -> Path:
    pins.filleted_pin(folder / "pin.stl", shape)
    pins.hole_block(folder / "hole.stl", shape, CLEARANCE_MM)
    return folder


@pytest.mark.parametrize("shape", ["cross", "slot"])
def test_a_filleted_pin_goes_from_one_stl_through_coacd_to_a_trial(
    cli: Path, tmp_path: Path, shape: str
) -> None:
    parts = pair(tmp_path, shape)
    cache = parts / "cache"
    env = {"PEGTWIN_PYTHON": sys.executable, "XDG_CACHE_HOME": str(cache)}
    o = run(cli, "assembly", "decompose", str(parts / "pin.stl"), "--units", "mm",
            "--clearance-mm", str(CLEARANCE_MM), "--out", str(parts / "pin_parts"), env=env)
    assert o.returncode == 0, o.stderr
    deviation = float(re.search(r"([0-9.]+) mm off its surface", o.stdout).group(1))
    assert deviation <= CLEARANCE_MM / 4, o.stdout
    written = sorted((parts / "pin_parts").glob("part_*.stl"))
    assert len(written) > 1, o.stdout

    (parts / "pin.toml").write_text(
        f'name = "filleted-{shape}"\nclearance_mm = {CLEARANCE_MM}\n'
        '[peg]\nmesh = "pin.stl"\nunits = "mm"\ndecompose = "coacd"\n'
        '[hole]\nmesh = "hole.stl"\nunits = "mm"\n'
    )
    o = run(cli, "assembly", "check", str(parts / "pin.toml"), "--json", env=env)
    assert o.returncode == 0, o.stderr
    report = json.loads(o.stdout)
    assert report["peg"]["pieces"] == len(written)
    assert report["peg"]["max_deviation_mm"] <= report["clearance_min_mm"] / 4
    assert abs(report["clearance_min_mm"] - CLEARANCE_MM) < 0.2, report
    assert report["seat"] == "tip_on_floor"
    assert any("(cached)" in w for w in report["warnings"]), report["warnings"]

    o = run(cli, "trial", "--assembly", str(parts / "pin.toml"), "--method", "direct",
            "--seed", "1", "--json", env=env)
    assert o.returncode == 0, o.stderr
    record = json.loads(o.stdout)
    assert record["outcome"] in ("success", "failure"), record


def test_a_missing_coacd_or_python_is_refused_by_name(cli: Path, tmp_path: Path) -> None:
    parts = pair(tmp_path, "cross")
    no_coacd = tmp_path / "python-without-coacd"
    no_coacd.write_text(
        "#!/bin/sh\n"
        f'exec "{sys.executable}" -c "import sys; sys.modules[\'coacd\'] = None; '
        'exec(compile(sys.argv[1], \'coacd.py\', \'exec\'))" "$2"\n'
    )
    no_coacd.chmod(0o755)
    for python, said in [(str(no_coacd), "pip install coacd"), (str(tmp_path / "nope"), "cannot run")]:
        out = tmp_path / f"out-{Path(python).name}"
        o = run(cli, "assembly", "decompose", str(parts / "pin.stl"), "--units", "mm",
                "--clearance-mm", "0.9", "--out", str(out),
                "--cache-dir", str(tmp_path / "cache"), env={"PEGTWIN_PYTHON": python})
        assert o.returncode == 2, o.stderr
        assert said in o.stderr and "pin.stl" in o.stderr, o.stderr
        assert not out.exists()
