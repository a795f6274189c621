"""The quickstart campaign from Python, then success against the estimate's orientation error.

    .venv/bin/pip install ./python matplotlib
    .venv/bin/python python/examples/campaign_analysis.py [--out results-quickstart]

Runs `scenarios/quickstart.toml` (the cross at 0.5 mm, the manifold method at t_obs 6 and 10 s
and the direct baseline, 10 trials each; a few minutes on two cores, the reference manifold is
built once and cached), resumes the folder if it exists, loads the trials into pandas, prints
the success rate per cell and plots success against the estimate's orientation error (the
paper's Fig. 5 asks the same question) into `success_vs_orientation_error.png`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import pegtwin  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def progress(done: int, total: int) -> None:
    print(f"\r{done}/{total} trials", end="", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results-quickstart", help="campaign folder")
    parser.add_argument("--scenario", default=str(REPO / "scenarios" / "quickstart.toml"))
    args = parser.parse_args()

    out = Path(args.out)
    pegtwin.campaign(args.scenario, out, resume=out.exists(), progress=progress)
    print()

    trials = pegtwin.load_trials(out)
    rates = trials.groupby(["method", "t_obs_s"])["success"].agg(["mean", "count"])
    print(rates.rename(columns={"mean": "success rate", "count": "trials"}))

    estimated = trials[trials["method"] == "manifold"].copy()
    estimated["orientation_error_deg"] = np.sqrt(
        estimated["error_roll_deg"] ** 2
        + estimated["error_pitch_deg"] ** 2
        + estimated["error_yaw_deg"] ** 2
    )
    fig, ax = plt.subplots(figsize=(6, 4))
    for success, group in estimated.groupby("success"):
        ax.scatter(
            group["orientation_error_deg"],
            group["t_obs_s"] + np.where(success, 0.1, -0.1),
            label="success" if success else "failure",
            color="tab:green" if success else "tab:red",
        )
    ax.set_xlabel("orientation error of the estimate, deg")
    ax.set_ylabel("observation time, s")
    ax.set_title("cross at 0.5 mm: success against orientation error")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "success_vs_orientation_error.png", dpi=120)
    print(f"figure: {out / 'success_vs_orientation_error.png'}")


if __name__ == "__main__":
    main()
