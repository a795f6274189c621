"""pegtwin's MJCF reading against MuJoCo's own compiler: models that use every feature pegtwin
reads (each orientation specifier, angle units and Euler sequences, fromto, nested default
classes with class and childclass, frames, includes, meshdir and assetdir, mesh scale,
refpos and refquat, every primitive type, contype/conaffinity/group) are compiled by the
`mujoco` package, and each collision geom's pose in its part's body frame and its size must
agree with what `pegtwin assembly mjcf` prints to 1e-9 m / rad. Mesh vertices are compared
in the body frame to MuJoCo's float32 precision (MuJoCo stores them as float)."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco  # the test extras install it: the reference must be there, not skipped
import numpy as np
import pytest

from conftest import run_cli

TET = "v 0 0 0\nv 10 0 0\nv 0 20 0\nv 0 0 30\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
WEDGE = (
    "v 0 0 0\nv 8 0 0\nv 0 6 0\nv 0 0 12\nv 8 0 12\nv 0 6 12\n"
    "f 1 3 2\nf 4 5 6\nf 1 2 5\nf 1 5 4\nf 2 3 6\nf 2 6 5\nf 3 1 4\nf 3 4 6\n"
)

DEFAULTS = """<mujoco>
  <default>
    <geom contype="1" conaffinity="1"/>
    <mesh scale="0.001 0.001 0.001"/>
    <default class="part">
      <geom type="box" size=".005 .005 .005" group="1"/>
      <default class="slanted">
        <geom type="cylinder" size=".007 .012" xyaxes="0 1 0 -1 0 1"/>
      </default>
    </default>
    <default class="framed">
      <geom type="capsule" size=".002 .006" axisangle="0 0 1 45"/>
    </default>
    <default class="big"><mesh scale="0.002 0.0025 0.002"/></default>
  </default>
</mujoco>
"""

MAIN = """<mujoco model="every-feature">
  <compiler meshdir="meshes" eulerseq="zyx"/>
  <include file="defaults.xml"/>
  <asset>
    <mesh name="tet" file="tet.obj" scale="0.001 0.002 0.0015" refpos="0.5 1 2"
          refquat="0.9 0.1 0.3 -0.2"/>
    <mesh file="wedge.obj" class="big"/>
  </asset>
  <worldbody>
    <body name="base" pos="0.1 0.2 0.3" euler="10 20 30">
      <body name="part" pos="0.01 -0.02 0.03" axisangle="1 1 0 30" childclass="part">
        <geom name="box_q" type="box" size=".01 .02 .03" pos=".1 0 0" quat="0.8 0.2 -0.1 0.4"/>
        <geom name="box_e" type="box" size=".01 .02 .03" euler="15 -25 40"/>
        <geom name="plain"/>
        <geom name="sph_aa" type="sphere" size=".012" axisangle="0 1 2 75" pos="0 .05 0"/>
        <geom name="cap_part_size" type="capsule" size=".004" pos="0 -.05 0"/>
        <geom name="cap_xy" type="capsule" size=".004 .02" xyaxes="1 1 0 -1 2 0.5"/>
        <geom name="cyl_z" type="cylinder" size=".005 .01" zaxis="0 -1 1" pos="0 0 .1"/>
        <geom name="cyl_down" type="cylinder" size=".005 .01" zaxis="0 0 -1"/>
        <geom name="ell" type="ellipsoid" size=".01 .02 .015" pos="-.05 0 0" euler="5 6 7"/>
        <geom name="cap_ft" type="capsule" fromto="0 0 0 .01 .02 .03" size=".003"/>
        <geom name="cyl_ft" type="cylinder" fromto="0 0 0 0 0 -.04" size=".006"/>
        <geom name="box_ft" type="box" fromto=".01 0 0 .03 .01 -.02" size=".004 .009"/>
        <geom name="ell_ft" type="ellipsoid" fromto="0 .01 0 0 .03 0" size=".005"/>
        <geom name="cls" class="slanted"/>
        <geom name="cls_override" class="slanted" quat="1 0 0 0" pos="0 0 .02"/>
        <geom name="tet_geom" type="mesh" mesh="tet" pos=".02 .01 0" euler="30 0 0"/>
        <geom name="wedge_geom" type="mesh" mesh="wedge" zaxis="1 0 0"/>
        <geom name="visual" type="box" size=".1 .1 .1" contype="0" conaffinity="0" group="2"/>
        <geom name="only_aff" type="sphere" size=".003" contype="0" conaffinity="2" group="3"/>
        <frame pos="0 0 .2" euler="0 90 0" childclass="framed">
          <geom name="in_frame"/>
          <body name="child" pos=".03 0 0" xyaxes="0 1 0 0 0 1">
            <geom name="child_box" type="box" size=".002 .003 .004"/>
            <include file="parts/inner.xml"/>
          </body>
        </frame>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

INNER = """<mujoco>
  <geom name="inc_geom" type="ellipsoid" size=".001 .002 .003" pos="0 0 .01"/>
</mujoco>
"""

RADIAN = """<mujoco model="radians">
  <compiler angle="radian" eulerseq="XYZ" assetdir="assets"/>
  <asset><mesh name="tet" file="tet.obj" scale="0.01 0.01 0.01"/></asset>
  <worldbody>
    <body name="part" euler="0.1 0.2 0.3">
      <geom name="e" type="box" size=".01 .02 .03" euler="0.3 -0.5 1.1"/>
      <geom name="aa" type="capsule" size=".01 .02" axisangle="1 0 0 1.2"/>
      <geom name="m" type="mesh" mesh="tet" euler="0.2 0.1 0"/>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture()
def models(tmp_path: Path) -> dict[str, Path]:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "assets").mkdir()
    (tmp_path / "parts").mkdir()
    (tmp_path / "meshes" / "tet.obj").write_text(TET)
    (tmp_path / "meshes" / "wedge.obj").write_text(WEDGE)
    (tmp_path / "assets" / "tet.obj").write_text(TET)
    (tmp_path / "defaults.xml").write_text(DEFAULTS)
    (tmp_path / "parts" / "inner.xml").write_text(INNER)
    (tmp_path / "main.xml").write_text(MAIN)
    (tmp_path / "radian.xml").write_text(RADIAN)
    return {"main": tmp_path / "main.xml", "radian": tmp_path / "radian.xml"}


def mujoco_geoms(path: Path, body: str) -> dict[str, dict]:
    """MuJoCo's collision geoms of `body` and the bodies below it, in `body`'s frame."""
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    b = model.body(body).id
    below = {b}
    for i in range(model.nbody):
        if model.body_parentid[i] in below and i != 0:
            below.add(i)
    rb, pb = data.xmat[b].reshape(3, 3), data.xpos[b]
    out = {}
    for g in range(model.ngeom):
        if model.geom_bodyid[g] not in below:
            continue
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        rg, pg = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g]
        entry = {
            "type": mujoco.mjtGeom(model.geom_type[g]).name.removeprefix("mjGEOM_").lower(),
            "rot": rb.T @ rg,
            "pos": rb.T @ (pg - pb),
            "size": model.geom_size[g].copy(),
            "contype": int(model.geom_contype[g]),
            "conaffinity": int(model.geom_conaffinity[g]),
        }
        if entry["type"] == "mesh":
            m = model.geom_dataid[g]
            start, n = model.mesh_vertadr[m], model.mesh_vertnum[m]
            local = model.mesh_vert[start:start + n].astype(float)
            entry["vertices"] = (rb.T @ (rg @ local.T + (pg - pb)[:, None])).T
        out[model.geom(g).name] = entry
    return out


def pegtwin_geoms(cli: Path, path: Path, body: str) -> dict[str, dict]:
    o = run_cli(cli, "assembly", "mjcf", str(path), "--body", body)
    assert o.returncode == 0, o.stderr
    out = {}
    for line in o.stdout.splitlines():
        g = json.loads(line)
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, np.array(g["quat"]))
        g["rot"] = rot.reshape(3, 3)
        g["pos"] = np.array(g["pos"])
        out[g["name"]] = g
    return out


def same_points(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Each point of either set within `tol` of one of the other's."""
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    return bool(d.min(axis=1).max() <= tol and d.min(axis=0).max() <= tol)


@pytest.mark.parametrize("model", ["main", "radian"])
def test_every_collision_geom_is_where_mujoco_puts_it(
    cli: Path, models: dict[str, Path], model: str
) -> None:
    theirs = mujoco_geoms(models[model], "part")
    ours = pegtwin_geoms(cli, models[model], "part")
    assert sorted(ours) == sorted(theirs)
    for name, t in theirs.items():
        o = ours[name]
        assert o["type"] == t["type"], name
        assert (o["contype"], o["conaffinity"]) == (t["contype"], t["conaffinity"]), name
        if t["type"] == "mesh":
            scale = np.abs(t["vertices"]).max()
            assert same_points(np.array(o["vertices"]), t["vertices"], 1e-6 * scale), name
            continue
        assert np.abs(o["pos"] - t["pos"]).max() < 1e-9, (name, o["pos"], t["pos"])
        assert np.abs(o["rot"] - t["rot"]).max() < 1e-9, (name, o["rot"], t["rot"])
        used = {"sphere": 1, "capsule": 2, "cylinder": 2}.get(t["type"], 3)
        size = np.array(o["size"])[:used] - t["size"][:used]
        assert np.abs(size).max() < 1e-9, (name, o["size"], t["size"])


def test_the_models_use_every_feature(models: dict[str, Path]) -> None:
    """A guard on the test itself: a feature dropped from the models fails here."""
    text = "".join(p.read_text() for p in models["main"].parent.rglob("*.xml"))
    for feature in [
        "quat=", "axisangle=", "xyaxes=", "zaxis=", "euler=", 'angle="radian"', "eulerseq=",
        "fromto=", 'size=".004"', "<default class=", "childclass=", "class=", "<include", "meshdir=",
        "assetdir=", "scale=", "refpos=", "refquat=", "<frame", 'type="sphere"',
        'type="capsule"', 'type="cylinder"', 'type="ellipsoid"', 'type="box"', 'type="mesh"',
        "contype=", "conaffinity=", "group=",
    ]:
        assert feature in text, feature
