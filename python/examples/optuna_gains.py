"""An Optuna study over the manifold method's insertion gains: success up, peak force down.

    .venv/bin/pip install ./python optuna
    .venv/bin/python python/examples/optuna_gains.py --study runs/gains.db --n-trials 40

Each Optuna trial proposes the insertion's x, y stiffness (N/m), rotational stiffness
(N m/rad) and damping ratio, lays them over the scenario as a `[gains.insert]` section
(`pegtwin.evaluate`), runs trials 0 .. --trials-per-candidate - 1 of every cell (the same seeds,
so the same hole offsets, for every candidate: common random numbers), and reports two objectives:
the success rate (maximised) and the mean peak |Fz| of the successes (minimised; 1000 N when
none succeeded). The search is multi-objective (NSGA-II, seeded) and stored in SQLite, so a killed
study goes on where it was when run again with the same --study; the Pareto front is printed
as scenario snippets at the end. The ranges are those of `pegtwin tune` (docs/campaigns.md),
inside KUKA Sunrise's.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import optuna

import pegtwin

REPO = Path(__file__).resolve().parents[2]
NO_SUCCESS_FZ_N = 1000.0


def snippet(params: dict) -> str:
    """The candidate as a scenario's `[gains.insert]` section (z kept at 2000 N/m, as `tune`)."""
    t, r, d = params["insert_n_per_m"], params["insert_nm_per_rad"], params["insert_damping"]
    return (
        "[gains.insert]\n"
        f"stiffness = [{t:.1f}, {t:.1f}, 2000.0, {r:.2f}, {r:.2f}, {r:.2f}]\n"
        f"damping_ratio = [{d:.3f}, {d:.3f}, {d:.3f}, {d:.3f}, {d:.3f}, {d:.3f}]\n"
    )


def objective(args: argparse.Namespace):
    def run(trial: optuna.Trial) -> tuple:
        params = {
            "insert_n_per_m": trial.suggest_float("insert_n_per_m", 300.0, 5000.0, log=True),
            "insert_nm_per_rad": trial.suggest_float("insert_nm_per_rad", 10.0, 300.0, log=True),
            "insert_damping": trial.suggest_float("insert_damping", 0.3, 1.0),
        }
        records = pegtwin.evaluate(
            args.scenario, snippet(params), trials=range(0, args.trials_per_candidate),
            threads=args.threads, cache_dir=args.cache_dir,
        )
        success = float(records["success"].mean())
        peaks = records.loc[records["success"], "peak_fz_n"]
        return success, float(peaks.mean()) if len(peaks) else NO_SUCCESS_FZ_N

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default=str(REPO / "scenarios" / "quickstart.toml"))
    parser.add_argument("--study", default="optuna-gains.db", help="SQLite file of the study")
    parser.add_argument("--n-trials", type=int, default=40, help="candidates in all (resumed ones count)")
    parser.add_argument("--trials-per-candidate", type=int, default=4)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--cache-dir", default=None)
    args = parser.parse_args()

    study = optuna.create_study(
        study_name="pegtwin-insertion-gains",
        storage=f"sqlite:///{Path(args.study).resolve()}",
        load_if_exists=True,
        directions=["maximize", "minimize"],
        sampler=optuna.samplers.NSGAIISampler(seed=args.seed),
    )
    done = len([t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE])
    if done < args.n_trials:
        study.optimize(objective(args), n_trials=args.n_trials - done)
    for best in study.best_trials:
        success, fz = best.values
        print(f"# trial {best.number}: success {success:.0%}, mean peak Fz {fz:.1f} N")
        print(snippet(best.params))


if __name__ == "__main__":
    main()
