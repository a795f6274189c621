#!/usr/bin/env bash
# Runs a pegtwin campaign on a Slurm cluster as three dependent jobs (deploy/README.md):
#   1. manifolds.sbatch  every reference manifold the scenario needs, into the shared cache;
#   2. shard.sbatch      a job array of N tasks, task I running shard I/N (`--shard auto`);
#   3. merge.sbatch      the shards joined into OUT, with the report.
# Usage: deploy/slurm/submit.sh [--wait] SCENARIO OUT N [CAMPAIGN OPTIONS...]
#   --wait             return when the merge has finished, with its exit status;
#   CAMPAIGN OPTIONS   passed to each shard's `pegtwin campaign` (e.g. --replays none --threads 8).
# Environment: PEGTWIN (the pegtwin binary; default: pegtwin on the PATH), PEGTWIN_CACHE_DIR (the
# manifold cache, on a file system every node sees; default: pegtwin's, ~/.cache/pegtwin), and
# Slurm's own SBATCH_* input variables for the jobs' options (SBATCH_PARTITION, SBATCH_TIMELIMIT,
# SBATCH_ACCOUNT, ...). The work folder OUT.slurm/ holds the shards and the jobs' logs.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
usage="usage: $0 [--wait] SCENARIO OUT N [CAMPAIGN OPTIONS...]"
wait=()
if [ "${1:-}" = "--wait" ]; then wait=(--wait); shift; fi
[ $# -ge 3 ] || { echo "$usage" >&2; exit 2; }
scenario=$1
out=$2
count=$3
shift 3
if [ ! -f "$scenario" ]; then
  echo "$0: SCENARIO $scenario: not a file (expected a scenario TOML)" >&2; exit 2
fi
if ! [[ "$count" =~ ^[1-9][0-9]*$ ]]; then
  echo "$0: N $count: expected the number of shards, a whole number of at least 1" >&2; exit 2
fi
if [ -e "$out" ] && [ -n "$(ls -A "$out" 2>/dev/null)" ]; then
  echo "$0: OUT $out: exists and is not empty (expected a new folder for the merged results)" >&2
  exit 2
fi
command -v sbatch >/dev/null || { echo "$0: sbatch not found (a Slurm client is needed)" >&2; exit 2; }
export PEGTWIN=${PEGTWIN:-pegtwin}
command -v "$PEGTWIN" >/dev/null || {
  echo "$0: PEGTWIN $PEGTWIN: not found (put pegtwin on the PATH: cargo install --path .)" >&2; exit 2
}
export PEGTWIN=$(command -v "$PEGTWIN")
absolute() { (cd "$(dirname "$1")" && echo "$PWD/$(basename "$1")"); }
mkdir -p "$out"
scenario=$(absolute "$scenario")
out=$(absolute "$out")
work="$out.slurm"
mkdir -p "$work/logs" "$work/shards"
if [ -n "${PEGTWIN_CACHE_DIR:-}" ]; then
  mkdir -p "$PEGTWIN_CACHE_DIR"
  export PEGTWIN_CACHE_DIR=$(cd "$PEGTWIN_CACHE_DIR" && pwd)
fi

build=$(sbatch --parsable --output="$work/logs/%x-%j.out" "$here/manifolds.sbatch" "$scenario")
array=$(sbatch --parsable --dependency="afterok:$build" --kill-on-invalid-dep=yes \
  --array="0-$((count - 1))" --output="$work/logs/%x-%A_%a.out" \
  "$here/shard.sbatch" "$scenario" "$work/shards" "$@")
echo "submitted: manifolds $build, shards $array (array of $count), logs in $work/logs"
merge=$(sbatch --parsable "${wait[@]}" --dependency="afterok:$array" --kill-on-invalid-dep=yes \
  --output="$work/logs/%x-%j.out" "$here/merge.sbatch" "$work/shards" "$count" "$out") || {
  status=$?
  echo "the merge job failed (exit $status): see $work/logs" >&2
  exit "$status"
}
merge=${merge%%;*}
if [ ${#wait[@]} -gt 0 ]; then
  # sbatch --wait returns 0 for a job cancelled before it ran (a failed job it depended on).
  state=$(scontrol show job "$merge" -o | grep -o 'JobState=[A-Z_]*' || true)
  if [ "$state" != "JobState=COMPLETED" ]; then
    echo "the merge job $merge did not complete (${state:-its state is unknown}): a job it" \
      "depends on failed; see $work/logs" >&2
    exit 1
  fi
  echo "merge $merge finished: results in $out"
else
  echo "submitted: merge $merge; results in $out when it finishes"
fi
