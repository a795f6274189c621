"""The package's API against the command line: same records, same errors, DataFrames."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import pegtwin
from conftest import run_cli


def cli_trial(cli: Path, *args: str) -> dict:
    o = run_cli(cli, "trial", *args, "--json")
    assert o.returncode == 0, o.stderr
    return json.loads(o.stdout)


def test_a_direct_trial_is_the_command_lines_record(cli: Path) -> None:
    record = pegtwin.trial(geometry="cross", clearance_mm=0.5, seed=3, method="direct", t_obs_s=2)
    expected = cli_trial(
        cli, "--geometry", "cross", "--clearance-mm", "0.5", "--seed", "3",
        "--method", "direct", "--t-obs", "2",
    )
    assert record == expected
    assert record["method"] == "direct" and record["seed"] == 3


def test_an_assembly_trial_is_the_command_lines_record(cli: Path, cross_assembly: Path) -> None:
    assembly = cross_assembly
    record = pegtwin.trial(assembly=assembly, seed=3, method="direct", t_obs_s=2)
    expected = cli_trial(
        cli, "--assembly", str(assembly), "--seed", "3", "--method", "direct", "--t-obs", "2"
    )
    assert record == expected
    assert record["geometry"] == "mine" and record["clearance_mm"] == 0.5
    with pytest.raises(ValueError, match="give geometry and clearance_mm"):
        pegtwin.trial("cross", 0.5, assembly=assembly)


def test_a_manifold_trial_is_the_command_lines_record(cli: Path, small_manifold: Path) -> None:
    record = pegtwin.trial(
        "cross", 0.5, seed=5, t_obs_s=3, offset_mm=2, offset_deg=1, manifold=small_manifold
    )
    expected = cli_trial(
        cli, "--geometry", "cross", "--clearance-mm", "0.5", "--seed", "5", "--t-obs", "3",
        "--offset-mm", "2", "--offset-deg", "1", "--manifold", str(small_manifold),
    )
    assert record == expected
    assert record["errors"] is not None and record["outcome"] in ("success", "failure")


def test_a_geometric_manifold_trial_is_the_command_lines_record(cli: Path, tmp_path: Path) -> None:
    # The command line builds the cached geometric manifold; the package must find and use it.
    cache = tmp_path / "cache"
    expected = cli_trial(
        cli, "--geometry", "cross", "--clearance-mm", "0.5", "--seed", "6", "--t-obs", "3",
        "--sampler", "geometric", "--cache-dir", str(cache),
    )
    record = pegtwin.trial("cross", 0.5, seed=6, t_obs_s=3, sampler="geometric", cache_dir=cache)
    assert record == expected
    assert any("-geo" in p.name for p in cache.glob("*.manifold")), list(cache.iterdir())
    with pytest.raises(ValueError, match="sampler 'lidar'"):
        pegtwin.trial("cross", 0.5, sampler="lidar")


@pytest.mark.parametrize(
    "kwargs, cli_args",
    [
        (dict(geometry="cross", clearance_mm=99), ["--geometry", "cross", "--clearance-mm", "99"]),
        (dict(geometry="donut", clearance_mm=0.5), ["--geometry", "donut", "--clearance-mm", "0.5"]),
        (
            dict(geometry="cross", clearance_mm=0.5, offset_mm=80),
            ["--geometry", "cross", "--clearance-mm", "0.5", "--offset-mm", "80"],
        ),
        (
            dict(geometry="cross", clearance_mm=0.5, t_obs_s=0.01),
            ["--geometry", "cross", "--clearance-mm", "0.5", "--t-obs", "0.01"],
        ),
        (
            dict(geometry="cross", clearance_mm=0.5, manifold="/nonexistent/m.manifold"),
            ["--geometry", "cross", "--clearance-mm", "0.5", "--manifold", "/nonexistent/m.manifold"],
        ),
    ],
)
def test_bad_arguments_raise_value_error_with_the_command_lines_message(
    cli: Path, kwargs: dict, cli_args: list
) -> None:
    o = run_cli(cli, "trial", *cli_args)
    assert o.returncode == 2
    message = o.stderr.strip().removeprefix("error: ")
    with pytest.raises(ValueError) as raised:
        pegtwin.trial(**kwargs)
    assert str(raised.value) == message


def test_names_the_command_line_spells_as_flags_are_checked_too() -> None:
    expected = "method 'fast': expected manifold, direct, adaptive or active"
    with pytest.raises(ValueError, match=expected):
        pegtwin.trial("cross", 0.5, method="fast")
    with pytest.raises(ValueError, match="start 'side': expected partial or above"):
        pegtwin.trial("cross", 0.5, start="side")


def test_the_gil_is_released_while_a_trial_runs() -> None:
    ticks = 0
    worker = threading.Thread(
        target=pegtwin.trial, args=("cross", 0.5), kwargs=dict(method="direct", t_obs_s=1)
    )
    worker.start()
    while worker.is_alive():
        ticks += 1
        time.sleep(0.001)
    worker.join()
    assert ticks > 50, ticks


def test_a_campaign_writes_its_folder_and_loads_as_dataframes(
    cli: Path, scenario: Path, tmp_path: Path
) -> None:
    seen = []
    out = pegtwin.campaign(
        scenario, tmp_path / "run", threads=2, cache_dir=tmp_path / "cache",
        progress=lambda done, total: seen.append((done, total)),
    )
    assert out == str(tmp_path / "run")
    assert (tmp_path / "run" / "report.html").is_file()
    assert seen[0] == (0, 4) and seen[-1] == (4, 4)

    trials = pegtwin.load_trials(out)
    assert isinstance(trials, pd.DataFrame) and len(trials) == 4
    for column in [
        "cell", "trial", "seed", "geometry", "clearance_mm", "method", "t_obs_s", "outcome",
        "success", "final_depth_mm", "peak_fz_n", "mean_fz_n", "offset_x_mm", "offset_yaw_deg",
        "error_x_mm", "error_yaw_deg", "estimate_x_m", "fault_reason", "fault_source",
        "time_observe_s", "insert_fz_n", "insert_end", "estimate_std_x_m", "estimate_std_yaw_rad",
    ]:
        assert column in trials.columns, column
    assert set(trials["method"]) == {"manifold", "direct"}
    direct = trials[trials["method"] == "direct"]
    assert direct["error_x_mm"].isna().all()
    manifold = trials[trials["method"] == "manifold"]
    assert manifold["error_x_mm"].notna().all()
    assert direct["estimate_std_x_m"].isna().all()
    assert (manifold["estimate_std_x_m"] > 0).all()

    summary = pegtwin.load_summary(out)
    assert len(summary) == 2 and "geometry" in summary.columns
    assert summary.attrs["summary"]["cells"][0]["trials"] == 2

    # The command line's campaign of the same scenario holds the same records.
    o = run_cli(
        cli, "campaign", str(scenario), "--out", str(tmp_path / "cli"),
        "--cache-dir", str(tmp_path / "cache"), "--threads", "1",
    )
    assert o.returncode == 0, o.stderr
    same = (tmp_path / "cli" / "trials.jsonl").read_text()
    assert (tmp_path / "run" / "trials.jsonl").read_text() == same

    # `pegtwin export --parquet`: the same table, read by pyarrow and through load_trials.
    pq = pytest.importorskip("pyarrow.parquet")
    table_path = tmp_path / "trials.parquet"
    o = run_cli(cli, "export", out, "--parquet", str(table_path))
    assert o.returncode == 0, o.stderr
    table = pq.read_table(table_path)
    assert table.num_rows == 4
    assert str(table.schema.field("seed").type) == "uint64"
    assert str(table.schema.field("fault_time_s").type) == "double"
    assert list(table.column("seed").to_pylist()) == list(trials["seed"])
    exported = pegtwin.load_trials(table_path)
    assert set(exported.columns) == set(trials.columns)
    assert "real_cell_contact_friction" in trials.columns

    def missing(v: object) -> bool:
        return v is None or (isinstance(v, float) and np.isnan(v))

    for column in trials.columns:
        for x, y in zip(exported[column], trials[column]):
            if column in ("estimate_covariance", "insert_fz_n", "real_cell_wrench_bias"):
                x = None if x is None else [list(r) if hasattr(r, "__len__") else r for r in x]
                assert x == y or (missing(x) and missing(y)), (column, x, y)
            else:
                assert x == y or (pd.isna(x) and pd.isna(y)), (column, x, y)
    o = run_cli(cli, "export", str(tmp_path), "--parquet", str(tmp_path / "no.parquet"))
    assert o.returncode == 2 and "campaign.json" in o.stderr
    assert not (tmp_path / "no.parquet").exists()


def test_campaign_errors_are_value_errors(scenario: Path, tmp_path: Path, cli: Path) -> None:
    o = run_cli(cli, "campaign", str(scenario), "--out", str(tmp_path / "x"), "--threads", "0")
    with pytest.raises(ValueError) as raised:
        pegtwin.campaign(scenario, tmp_path / "y", threads=0)
    assert str(raised.value) == o.stderr.strip().removeprefix("error: ")
    with pytest.raises(ValueError, match="missing.toml"):
        pegtwin.campaign(tmp_path / "missing.toml", tmp_path / "z")
    with pytest.raises(ValueError, match="replays 'some'"):
        pegtwin.campaign(scenario, tmp_path / "w", replays="some")
    assert not (tmp_path / "y").exists() and not (tmp_path / "z").exists()
    with pytest.raises(ValueError, match="trials.jsonl"):
        pegtwin.load_trials(tmp_path)


def test_a_faulted_record_names_who_put_the_energy_in(tmp_path: Path) -> None:
    energy = {"window_s": 0.1, "mechanical_gain_j": 2.3, "drives_j": -0.5, "contacts_j": 3.4,
              "joint_damping_j": -0.3, "integration_j": -0.3, "source": "contacts"}
    record = {"cell": 0, "trial": 0, "seed": 1, "geometry": "gear", "clearance_mm": 0.1,
              "method": "direct", "outcome": "sim_fault", "offset": [0.0] * 6, "errors": None,
              "estimate": None, "final_depth_mm": 4.1, "times": {"observe_s": 0.674},
              "fault": {"time_s": 0.674, "reason": "runaway velocity", "energy": energy}}
    older = dict(record, trial=1, fault={"time_s": 1.0, "reason": "runaway velocity"})
    (tmp_path / "trials.jsonl").write_text(json.dumps(record) + "\n" + json.dumps(older) + "\n")
    trials = pegtwin.load_trials(tmp_path)
    assert trials["fault_source"][0] == "contacts" and pd.isna(trials["fault_source"][1])


def test_ctrl_c_stops_a_campaign_cleanly_and_it_resumes(scenario: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    cache = tmp_path / "cache"

    def interrupt_after_the_first(done: int, total: int) -> None:
        if done == 1:
            os.kill(os.getpid(), signal.SIGINT)

    # Python ignores SIGINT when it starts with it ignored (a shell's background job, some CI
    # runners); Ctrl-C's own handler is what this test is about, so install it.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            pegtwin.campaign(
                scenario, out, threads=1, cache_dir=cache, progress=interrupt_after_the_first
            )
    finally:
        signal.signal(signal.SIGINT, previous)
    kept = (out / "trials.jsonl").read_text().splitlines()
    assert 1 <= len(kept) < 4
    assert not (out / "summary.json").exists()
    pegtwin.campaign(scenario, out, threads=1, cache_dir=cache, resume=True)
    assert len(pegtwin.load_trials(out)) == 4


def test_a_manifold_loads_as_arrays_and_registers(cli: Path, tmp_path: Path) -> None:
    m, obs = tmp_path / "cross.manifold", tmp_path / "obs.csv"
    o = run_cli(
        cli, "manifold", "synth", "--shape", "cross", "--clearance-mm", "0.5",
        "--points", "20000", "--out", str(m), "--observations", str(obs),
        "--observation-count", "300", "--true-pose", "0.6,0.05,0.2,0,0,0.3",
    )
    assert o.returncode == 0, o.stderr
    manifold = pegtwin.Manifold.load(m)
    assert len(manifold) == 20000
    assert manifold.points.shape == (20000, 6) and manifold.points.dtype == np.float64
    assert np.allclose(np.linalg.norm(manifold.normals, axis=1), 1.0, atol=1e-6)
    assert manifold.meta["units"] == "m, rad"

    observations = np.loadtxt(obs, delimiter=",", skiprows=1)
    init = [0.601, 0.049, 0.2, 0.0, 0.0, 0.31]
    result = pegtwin.register(manifold, observations, init)
    truth = np.array([0.6, 0.05, 0.2, 0.0, 0.0, 0.3])
    # x, y and yaw are what a synthetic extrusion pins down (as tests/manifold_cli.rs checks).
    assert np.abs(result["estimate"][:2] - truth[:2]).max() < 0.1e-3
    assert abs(result["estimate"][5] - truth[5]) < np.radians(0.1)
    assert len(result["restarts"]) == 8 and result["kept"] >= 1

    o = run_cli(
        cli, "register", "--manifold", str(m), "--observations", str(obs),
        "--init", ",".join(map(str, init)), "--json",
    )
    assert o.returncode == 0, o.stderr
    cli_estimate = json.loads(o.stdout)["estimate_base_T_hole"]
    assert np.array_equal(result["estimate"], np.asarray(cli_estimate))
    # The estimate's uncertainty: a positive std per axis, from a symmetric covariance.
    std, cov = result["estimate_std"], result["covariance"]
    assert std.shape == (6,) and np.all(std > 0) and np.all(np.isfinite(std))
    assert cov.shape == (6, 6) and np.allclose(cov, cov.T, rtol=1e-9, atol=0)
    assert np.allclose(np.sqrt(np.diag(cov)), std, rtol=1e-12, atol=0)
    assert np.array_equal(std, np.asarray(json.loads(o.stdout)["estimate_std"]))

    with pytest.raises(ValueError, match="expected \\(N, 6\\)"):
        pegtwin.register(manifold, observations[:, :5], init)
    with pytest.raises(ValueError, match="solver 'best'"):
        pegtwin.register(manifold, observations, init, solver="best")
    with pytest.raises(ValueError):
        pegtwin.register(manifold, observations[:3], init)
    with pytest.raises(ValueError, match="nothing.manifold"):
        pegtwin.Manifold.load(tmp_path / "nothing.manifold")


def test_a_trace_as_mcap_reads_back_as_the_csv_trace(cli: Path, tmp_path: Path) -> None:
    reader = pytest.importorskip("mcap.reader")
    args = ["trial", "--geometry", "cross", "--clearance-mm", "0.5", "--method", "direct",
            "--t-obs", "1", "--seed", "3"]
    for name in ["trace.csv", "trace.mcap"]:
        o = run_cli(cli, *args, "--trace", str(tmp_path / name))
        assert o.returncode == 0, o.stderr
    csv = pd.read_csv(tmp_path / "trace.csv")
    topics: dict = {}
    with open(tmp_path / "trace.mcap", "rb") as f:
        mcap = reader.make_reader(f)
        summary = mcap.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert schemas["/tcp/pose"] == "foxglove.PoseInFrame"
        for _, channel, message in mcap.iter_messages():
            assert channel.message_encoding == "json"
            topics.setdefault(channel.topic, []).append((message.log_time, json.loads(message.data)))
    assert set(topics) == {"/tcp/pose", "/tcp/pose_rpy", "/wrench/estimated", "/wrench/true", "/phase"}
    for samples in topics.values():
        assert len(samples) == len(csv)
    rpy = topics["/tcp/pose_rpy"]
    assert [t for t, _ in rpy] == [round(s * 1e9) for s in csv["time_s"]]
    # The CSV holds the same doubles, written with 17 significant digits or fewer.
    assert np.allclose([m["x"] for _, m in rpy], csv["x"], rtol=1e-15, atol=0)
    est = [m["force"]["z"] for _, m in topics["/wrench/estimated"]]
    assert np.allclose(est, csv["est_fz"], rtol=1e-15, atol=0)
    assert [m["phase"] for _, m in topics["/phase"]] == list(csv["phase"])
    pose = topics["/tcp/pose"][-1][1]["pose"]["orientation"]
    assert abs(sum(pose[k] ** 2 for k in "xyzw") - 1) < 1e-12
