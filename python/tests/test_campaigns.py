"""merge, check, rerun, tune and evaluate from Python: the command line's results, and the
Optuna example on a tiny budget (when optuna is installed)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import pegtwin

from conftest import REPO, run_cli


def records(folder: Path) -> list:
    return [json.loads(line) for line in (folder / "trials.jsonl").read_text().splitlines()]


def test_shards_merge_check_and_rerun_as_the_command_line(
    cli: Path, scenario: Path, tmp_path: Path
) -> None:
    cache = tmp_path / "cache"
    o = run_cli(cli, "campaign", str(scenario), "--out", str(tmp_path / "whole"),
                "--cache-dir", str(cache))
    assert o.returncode == 0, o.stderr
    shards = [tmp_path / f"shard{i}" for i in range(2)]
    for i, shard in enumerate(shards):
        pegtwin.campaign(scenario, shard, shard=f"{i}/2", cache_dir=cache)
    merged = pegtwin.merge(list(reversed(shards)), tmp_path / "merged", cache_dir=cache)
    whole = (tmp_path / "whole" / "trials.jsonl").read_text()
    assert (Path(merged) / "trials.jsonl").read_text() == whole

    baseline = tmp_path / "baseline.json"
    written = pegtwin.check(merged, write_baseline=baseline)
    assert written["cells"] == 2 and baseline.is_file()
    result = pegtwin.check(merged, baseline=baseline)
    assert result["passed"] and result["findings"]
    assert run_cli(cli, "check", merged, "--baseline", str(baseline)).returncode == 0
    with pytest.raises(ValueError, match="baseline"):
        pegtwin.check(merged)

    record = pegtwin.rerun(merged, 1, 1, cache_dir=cache)
    assert record == records(Path(merged))[3]
    with pytest.raises(ValueError, match="--cell 9"):
        pegtwin.rerun(scenario, 9, 0, cache_dir=cache)


def test_evaluate_runs_a_range_of_the_campaigns_trials_with_overrides(
    scenario: Path, tmp_path: Path
) -> None:
    cache = tmp_path / "cache"
    pegtwin.campaign(scenario, tmp_path / "run", cache_dir=cache)
    every = pegtwin.load_trials(tmp_path / "run")
    second = pegtwin.evaluate(scenario, trials=range(1, 2), cache_dir=cache)
    assert list(second["seed"]) == list(every[every["trial"] == 1]["seed"])
    assert list(second["peak_fz_n"]) == list(every[every["trial"] == 1]["peak_fz_n"])
    stiff = pegtwin.evaluate(
        scenario, "[gains.insert]\nstiffness = [4000, 4000, 2000, 200, 200, 200]\n",
        trials=range(1, 2), cache_dir=cache,
    )
    assert list(stiff["seed"]) == list(second["seed"]), "the same seeds for every candidate"
    assert list(stiff["peak_fz_n"]) != list(second["peak_fz_n"])
    with pytest.raises(ValueError, match="overrides"):
        pegtwin.evaluate(scenario, "[gains.insert", cache_dir=cache)
    with pytest.raises(ValueError, match="stiffness"):
        pegtwin.evaluate(scenario, "[gains.insert]\nstiffness = 3\n", cache_dir=cache)
    with pytest.raises(ValueError, match="trials 0..5"):
        pegtwin.evaluate(scenario, trials=range(0, 5), cache_dir=cache)


def test_tune_writes_its_table(scenario: Path, tmp_path: Path) -> None:
    table = pegtwin.tune(scenario, tmp_path / "tune", candidates=2, first_trials=1,
                         cache_dir=tmp_path / "cache")
    # rung 0: two candidates and the scenario's own settings x 1 trial; rung 1: the best x 2
    assert len(table) == 3 + 1
    assert table["incumbent"].sum() >= 1
    assert "[gains.insert]" in table.attrs["snippet"]
    assert (tmp_path / "tune" / "tune-journal.jsonl").is_file()
    with pytest.raises(ValueError, match="resume"):
        pegtwin.tune(scenario, tmp_path / "tune", candidates=2, first_trials=1)
    again = pegtwin.tune(scenario, tmp_path / "tune", candidates=2, first_trials=1,
                         cache_dir=tmp_path / "cache", resume=True)
    assert again.equals(table)


def test_the_optuna_example_runs_and_resumes_its_study(scenario: Path, tmp_path: Path) -> None:
    optuna = pytest.importorskip("optuna")
    study = tmp_path / "study.db"
    example = REPO / "python" / "examples" / "optuna_gains.py"

    def run(n: int) -> str:
        o = subprocess.run(
            [sys.executable, str(example), "--scenario", str(scenario), "--study", str(study),
             "--n-trials", str(n), "--trials-per-candidate", "1", "--threads", "2",
             "--cache-dir", str(tmp_path / "cache")],
            capture_output=True, text=True,
        )
        assert o.returncode == 0, o.stderr
        return o.stdout

    run(2)
    out = run(3)
    assert "[gains.insert]" in out
    loaded = optuna.load_study(study_name="pegtwin-insertion-gains", storage=f"sqlite:///{study}")
    assert len(loaded.trials) == 3, "the second run went on with the stored study"
