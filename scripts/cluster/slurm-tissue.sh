#!/usr/bin/env bash
# A tissue build on a Slurm cluster: rounds of a job array of N shards
# (`palpa tissue build … --shard I/N`), each followed by a merge job
# (`palpa tissue merge`) that starts when every shard of the round has ended. The merge
# either writes the file or submits the next round itself; where a shard failed or was
# killed, it submits the round again (each shard goes on from its log), up to --retries
# times.
#
#   scripts/cluster/slurm-tissue.sh [--shards N] [--partition P] [--time T] [--cpus C]
#       [--retries R] [--palpa PATH] -- BUILD_ARGS…   (BUILD_ARGS hold --out X.tissue)
#
# Prints the first round's job ids. What each job said is in X.tissue.slurm/; the
# merge writes X.tissue.slurm/status: `done`, or `failed: …`.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
shards=4 partition="" time_limit="" cpus=1 retries=2 palpa=palpa merge=0
while (($#)); do
  case "$1" in
    --shards) shards=$2; shift 2 ;;
    --partition) partition=$2; shift 2 ;;
    --time) time_limit=$2; shift 2 ;;
    --cpus) cpus=$2; shift 2 ;;
    --retries) retries=$2; shift 2 ;;
    --palpa) palpa=$2; shift 2 ;;
    --merge) merge=1; shift ;;
    --) shift; break ;;
    *) echo "slurm-tissue: unknown option $1 (the build's arguments go after --)" >&2; exit 2 ;;
  esac
done
args=("$@")
out=""
for ((k = 0; k < ${#args[@]}; k++)); do
  case "${args[k]}" in
    --out) out=${args[k+1]:-} ;;
    --out=*) out=${args[k]#--out=} ;;
  esac
done
[[ -n "$out" ]] || { echo "slurm-tissue: the build's arguments need --out X.tissue" >&2; exit 2; }
[[ "$shards" =~ ^[1-9][0-9]*$ ]] || { echo "slurm-tissue: --shards $shards: expected a count ≥ 1" >&2; exit 2; }
out=$(cd "$(dirname "$out")" && pwd)/$(basename "$out")
jobs_dir="$out.slurm"
mkdir -p "$jobs_dir"
palpa=$(command -v "$palpa" || echo "$palpa")

common=()
[[ -n "$partition" ]] && common+=(--partition "$partition")
[[ -n "$time_limit" ]] && common+=(--time "$time_limit")
quoted=$(printf '%q ' "${args[@]}")
self=$(printf '%q ' "$here/slurm-tissue.sh" --shards "$shards" --cpus "$cpus" --palpa "$palpa")
[[ -n "$partition" ]] && self+=$(printf '%q ' --partition "$partition")
[[ -n "$time_limit" ]] && self+=$(printf '%q ' --time "$time_limit")

# One round: the array, then the merge job once all of it has ended (afterany: a
# failed shard is the merge's to see and resubmit).
submit_round() {
  local left=$1 array merge_job
  array=$(sbatch --parsable "${common[@]}" --array="1-$shards" --cpus-per-task="$cpus" \
    --job-name=palpa-shard --output="$jobs_dir/shard-%A_%a.out" \
    --wrap "$(printf '%q ' "$palpa") tissue build $quoted --shard \$SLURM_ARRAY_TASK_ID/$shards --jobs $cpus")
  merge_job=$(sbatch --parsable "${common[@]}" --dependency="afterany:$array" \
    --job-name=palpa-merge --output="$jobs_dir/merge-%j.out" \
    --wrap "$self --retries $left --merge -- $quoted")
  echo "$array $merge_job"
}

if ((merge == 0)); then
  rm -f "$jobs_dir/status"
  submit_round "$retries"
  exit 0
fi

# The merge job: gather what the shards logged, then finish, go on, or retry.
shopt -s nullglob
logs=("$out".*shard-*.log "$out".shard-*.log)
mapfile -t logs < <(printf '%s\n' "${logs[@]}" | sort -u)
if result=$("$palpa" tissue merge "${logs[@]}" --out "$out" 2> "$jobs_dir/merge.err"); then
  echo "$result"
  if [[ -f "$out" ]]; then
    echo done > "$jobs_dir/status"
  else
    submit_round "$retries"
  fi
else
  cat "$jobs_dir/merge.err" >&2
  if ((retries > 0)); then
    echo "slurm-tissue: a shard is incomplete; the round again ($retries retries left)" >&2
    submit_round $((retries - 1))
  else
    echo "failed: $(tail -n 1 "$jobs_dir/merge.err")" > "$jobs_dir/status"
    exit 1
  fi
fi
