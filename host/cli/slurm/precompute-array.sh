#!/usr/bin/env bash
# precompute-array.sh - one transport file precomputed on a Slurm cluster:
# an array job of N shards (`haarlight precompute --shard I/N`, one task
# each), then a job that runs once they all succeeded and joins them
# (`haarlight merge`) into the same bytes as one whole run. Depends on
# Slurm's sbatch and scontrol, and on the haarlight command. With
# --bounces B (B >= 1) among the options it runs in two phases, as the
# bounces need every vertex's direct rows: the array and merge of the
# direct rows (the options without --bounces, --bounce-rays and
# --bounce-terms, with --keep-floats) into OUT.hlt.shards/direct.hlt and
# its floats direct.hlt.values, then a second array that
# gathers each shard's bounces from it (precompute --direct-rows) and the
# merge of those into OUT.hlt: the same bytes as one run with --bounces.
#
# One command submits both jobs:
#
#   precompute-array.sh submit [-s SBATCH_OPTION]... [-m SBATCH_OPTION]...
#                       [--wait [--poll S]] N MESH OUT.hlt [PRECOMPUTE_OPTION...]
#
#   e.g.  HAARLIGHT=~/haarlight/build/haarlight precompute-array.sh submit \
#           -s --partition=cpu -s --time=4:00:00 -s --cpus-per-task=16 \
#           -m --cpus-per-task=1 64 dragon.obj dragon.hlt --ground -N 64
#
#   N                 shards: the array is --array=0-(N-1) (at most the
#                     cluster's MaxArraySize, often 1001)
#   MESH, OUT.hlt     as `haarlight precompute MESH -o OUT.hlt`
#   PRECOMPUTE_OPTION any of precompute's options but -o, --shard and
#                     --resume, which this script sets; every shard and the
#                     merge must see the same ones
#   -s SBATCH_OPTION  passed to sbatch for both jobs (partition, account,
#                     time, cpus); repeat for several
#   -m SBATCH_OPTION  passed to sbatch for the merge job only, after the -s
#                     ones (sbatch takes the last of a repeated option)
#   --wait            return once the merge job has ended; exit 0 only if it
#                     completed, else list the tasks that did not
#   --poll S          with --wait, ask the controller for the merge job's
#                     state every S seconds (default 10)
#
# haarlight is $HAARLIGHT, else `haarlight` on PATH, resolved to a full
# path when submitting; MESH and OUT.hlt become full paths too. The
# compute nodes must see these paths (a shared file system). The shards
# and every job's log go to OUT.hlt.shards/; they are kept after the merge
# (remove them by hand). A task that is requeued (node failure,
# preemption) or submitted again continues its shard from the shard's
# .partial file (precompute --resume); a task whose shard is already whole
# is not run again (so after changing the options remove OUT.hlt.shards/:
# merge refuses shards made with other options). If a task fails, Slurm
# cancels the merge job (--kill-on-invalid-dep); submit again with the
# same arguments to redo only what is missing.
#
# The two job steps, which submit uses, can also be submitted by hand:
#   sbatch --array=0-(N-1) precompute-array.sh task N MESH SHARD_DIR [PRECOMPUTE_OPTION...]
#   sbatch --dependency=afterok:ARRAY_JOB_ID precompute-array.sh merge N OUT.hlt SHARD_DIR
# and with --bounces, after the direct rows' merge into SHARD_DIR/direct.hlt:
#   sbatch --array=0-(N-1) precompute-array.sh bounce-task N MESH SHARD_DIR [PRECOMPUTE_OPTION...]
#   sbatch --dependency=afterok:ID precompute-array.sh merge N OUT.hlt SHARD_DIR bounce
set -u

# the shard files' names inside SHARD_DIR, I counted from 0 (the array's
# task id); every name of a run carries N, so runs with another N never
# mix their shards
shard_name() { printf 'shard-%s-of-%s.hls' "$1" "$2"; }
bounce_name() { printf 'bounce-%s-of-%s.hls' "$1" "$2"; }

# the bounces the options ask for (0: none)
bounces_of() {
  local b=0
  while [ $# -gt 0 ]; do
    case "$1" in
      --bounces) b="${2:-0}"; shift ;;
      --bounces=*) b="${1#--bounces=}" ;;
    esac
    shift
  done
  echo "$b"
}

# the options without the bounces' own, one a line (the direct phase's)
without_bounces() {
  while [ $# -gt 0 ]; do
    case "$1" in
      --bounces|--bounce-rays|--bounce-terms) shift ;;
      --bounces=*|--bounce-rays=*|--bounce-terms=*) ;;
      *) printf '%s\n' "$1" ;;
    esac
    shift
  done
}

# usage [CODE]: the comment above; 2 (a usage error) unless asked for
usage() {
  sed -n '/^# One command submits/,/^#   sbatch --dependency/p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit "${1:-2}"
}
# die MESSAGE [CODE]: 2 for usage errors, 1 for the rest
die() { echo "precompute-array: $1" >&2; exit "${2:-1}"; }

# the haarlight binary: $HAARLIGHT, else PATH
find_haarlight() {
  local h="${HAARLIGHT:-}"
  if [ -z "$h" ]; then
    h="$(command -v haarlight)" || die "haarlight not found: set HAARLIGHT or put it on PATH" 2
  fi
  [ -x "$h" ] || die "HAARLIGHT=$h is not an executable file" 2
  echo "$h"
}

# --wait's default poll: one light request every 10 s costs the controller
# nothing and is a small delay against shards that take minutes
DEFAULT_POLL_S=10

is_count() { [[ "$1" =~ ^[1-9][0-9]*$ ]]; }

# the precompute options: this script owns -o, --shard and --resume
check_options() {
  local a
  for a in "$@"; do
    case "$a" in
      -o|--output|--output=*|--shard|--shard=*|--resume|--direct-rows|--direct-rows=*)
        die "precompute option $a is set by this script; leave it out" 2 ;;
    esac
  done
}

# a host thread per CPU Slurm gave the task, unless the options say: the
# words to add, one a line
task_threads() {
  if [ -n "${SLURM_CPUS_PER_TASK:-}" ] && ! printf '%s\n' "$@" | grep -q '^--threads'; then
    printf '%s\n' --threads "$SLURM_CPUS_PER_TASK"
  fi
}

# task_index N MODE: the array task's index, checked against N
task_index() {
  local n="$1" i="${SLURM_ARRAY_TASK_ID:-}"
  is_count "$n" || die "N must be a whole number >= 1, not '$n'" 2
  [ -n "$i" ] || die "$2: SLURM_ARRAY_TASK_ID is not set; submit with sbatch --array=0-$((n - 1))" 2
  [ "$i" -lt "$n" ] || die "$2: array task $i is outside 0..$((n - 1))" 2
  echo "$i"
}

task() {
  [ $# -ge 3 ] || usage
  local n="$1" mesh="$2" dir="$3"; shift 3
  local i hl shard
  i="$(task_index "$n" task)" || exit 2
  hl="$(find_haarlight)" || exit 2
  shard="$dir/$(shard_name "$i" "$n")"
  if [ -f "$shard" ] && [ ! -e "$shard.partial" ]; then
    echo "precompute-array: $shard is already whole; nothing to do"
    exit 0
  fi
  local threads=()
  mapfile -t threads < <(task_threads "$@")
  echo "precompute-array: shard $i/$n of $mesh on $(hostname) (job ${SLURM_JOB_ID:-?}, restart ${SLURM_RESTART_COUNT:-0})"
  # --resume continues the shard's .partial if a previous attempt left one
  # and starts afresh if not, so a requeued task loses at most a chunk
  exec "$hl" precompute "$mesh" --shard "$i/$n" -o "$shard" --resume "${threads[@]}" "$@"
}

# the bounces of shard SLURM_ARRAY_TASK_ID, from the merged direct rows
# in SHARD_DIR/direct.hlt; not resumable (it starts over if requeued)
bounce_task() {
  [ $# -ge 3 ] || usage
  local n="$1" mesh="$2" dir="$3"; shift 3
  local i hl shard
  i="$(task_index "$n" bounce-task)" || exit 2
  [ -f "$dir/direct.hlt" ] || die "bounce-task: $dir/direct.hlt (the merged direct rows) is missing"
  hl="$(find_haarlight)" || exit 2
  shard="$dir/$(bounce_name "$i" "$n")"
  if [ -f "$shard" ]; then
    echo "precompute-array: $shard is already whole; nothing to do"
    exit 0
  fi
  local threads=()
  mapfile -t threads < <(task_threads "$@")
  echo "precompute-array: bounce shard $i/$n of $mesh on $(hostname) (job ${SLURM_JOB_ID:-?})"
  exec "$hl" precompute "$mesh" --shard "$i/$n" -o "$shard" --direct-rows "$dir/direct.hlt" "${threads[@]}" "$@"
}

merge() {
  [ $# -eq 3 ] || [ $# -eq 4 ] || usage
  local n="$1" out="$2" dir="$3" kind="${4:-shard}"
  is_count "$n" || die "N must be a whole number >= 1, not '$n'" 2
  local hl i shards=(); hl="$(find_haarlight)" || exit 2
  for ((i = 0; i < n; i++)); do
    if [ "$kind" = bounce ]; then shards+=("$dir/$(bounce_name "$i" "$n")")
    else shards+=("$dir/$(shard_name "$i" "$n")"); fi
  done
  echo "precompute-array: merging $n shards from $dir into $out on $(hostname)"
  exec "$hl" merge -o "$out" "${shards[@]}"
}

# wait_job ID POLL_S: waits until the job has ended and prints its final
# state, or nothing if the controller has forgotten the job (MinJobAge
# after its end). Polls rather than `sbatch --wait`, which exits 0 even
# for a cancelled job and sleeps 2, 8, then 32 s between its looks.
wait_job() {
  local text state failures=0
  while :; do
    if text="$(scontrol show job -o "$1" 2>&1)"; then
      failures=0
      state="$(grep -o 'JobState=[A-Z_]*' <<<"$text" | head -n 1 | cut -d= -f2)"
      case "$state" in
        COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|PREEMPTED|BOOT_FAIL|DEADLINE|OUT_OF_MEMORY)
          echo "$state"; return 0 ;;
      esac
    elif grep -q 'Invalid job id' <<<"$text"; then
      return 0
    elif [ $((failures += 1)) -ge 30 ]; then # not a restart: say why and give up
      echo "precompute-array: scontrol cannot report job $1 (30 tries): $text" >&2
      echo "UNKNOWN"; return 0
    fi # else the controller did not answer (a restart): ask again
    sleep "$2"
  done
}

# report_merge ARRAY MERGE OUT DIR STATE: how the merge job ended
report_merge() {
  local array="$1" merge_id="$2" out="$3" dir="$4" state="$5"
  if [ "$state" = COMPLETED ] || { [ -z "$state" ] && [ -f "$out" ]; }; then
    echo "precompute-array: wrote $out"
    return 0
  fi
  echo "precompute-array: the merge job $merge_id ended ${state:-unknown}; the array's tasks:" >&2
  local line field
  scontrol show job -o "$array" 2>/dev/null | while read -r line; do
    for field in ArrayTaskId JobState ExitCode; do
      printf ' %s' "$(grep -o "$field=[^ ]*" <<<"$line" | head -n 1)"
    done
    echo
  done | sort -t= -k2 -n >&2
  echo "precompute-array: logs in $dir" >&2
  return 1
}

submit() {
  local common=() merge_only=() wait=0 poll="$DEFAULT_POLL_S"
  while [ $# -gt 0 ]; do
    case "$1" in
      -s) [ $# -ge 2 ] || usage; common+=("$2"); shift 2 ;;
      -m) [ $# -ge 2 ] || usage; merge_only+=("$2"); shift 2 ;;
      --wait) wait=1; shift ;;
      --poll) [ $# -ge 2 ] || usage
              [[ "$2" =~ ^[1-9][0-9]{0,3}$ ]] || die "--poll $2: expected whole seconds, 1 to 9999" 2
              poll="$2"; shift 2 ;;
      -h|--help) usage 0 ;;
      *) break ;;
    esac
  done
  [ $# -ge 3 ] || usage
  local n="$1" mesh="$2" out="$3"; shift 3
  is_count "$n" || die "N must be a whole number >= 1, not '$n'" 2
  check_options "$@"
  [ -f "$mesh" ] && [ -r "$mesh" ] || die "cannot read the mesh $mesh" 2
  local hl; hl="$(find_haarlight)" || exit 2
  "$hl" precompute --help 2>&1 | grep -q -- '--shard' \
    || die "$hl has no precompute --shard; use a newer haarlight" 2
  hl="$(realpath "$hl")" && mesh="$(realpath "$mesh")" && out="$(realpath -m "$out")" \
    || die "cannot resolve the paths" 2
  [ -d "$(dirname "$out")" ] || die "the folder of $out does not exist" 2
  local dir="$out.shards" self; self="$(realpath "$0")"
  mkdir -p "$dir" || die "cannot make $dir"

  local bounces direct_opts=() first_out="$out"
  bounces="$(bounces_of "$@")"
  [[ "$bounces" =~ ^[0-9]+$ ]] || die "--bounces $bounces: expected a whole number" 2
  if [ "$bounces" -gt 0 ]; then
    mapfile -t direct_opts < <(without_bounces "$@")
    # the shards' floats too (merged into direct.hlt.values), so that the
    # bounces start from them, not from the 8-bit codes
    direct_opts+=(--keep-floats)
    first_out="$dir/direct.hlt"
  else
    direct_opts=("$@")
  fi
  local array merge_id
  array="$(sbatch --parsable --job-name=hl-precompute --array="0-$((n - 1))" --requeue \
             --open-mode=append --output="$dir/task-%a.out" --export=ALL,HAARLIGHT="$hl" \
             "${common[@]}" "$self" task "$n" "$mesh" "$dir" "${direct_opts[@]}")" \
    || die "sbatch refused the array job"
  array="${array%%;*}" # --parsable prints ID[;CLUSTER]
  echo "precompute-array: array job $array: $n shards of $mesh into $dir"
  merge_id="$(sbatch --parsable --job-name=hl-merge --dependency="afterok:$array" --kill-on-invalid-dep=yes \
                --output="$dir/merge.out" --export=ALL,HAARLIGHT="$hl" \
                "${common[@]}" "${merge_only[@]}" "$self" merge "$n" "$first_out" "$dir")"
  local rc=$?
  merge_id="${merge_id%%;*}"
  [ "$rc" -eq 0 ] && [ -n "$merge_id" ] \
    || die "sbatch refused the merge job (exit $rc); cancel the array with: scancel $array"
  echo "precompute-array: merge job $merge_id writes $first_out once the array has succeeded"
  if [ "$bounces" -gt 0 ]; then
    # the second phase: each shard's bounces from the merged direct rows
    array="$(sbatch --parsable --job-name=hl-bounces --array="0-$((n - 1))" --requeue \
               --dependency="afterok:$merge_id" --kill-on-invalid-dep=yes \
               --open-mode=append --output="$dir/bounce-%a.out" --export=ALL,HAARLIGHT="$hl" \
               "${common[@]}" "$self" bounce-task "$n" "$mesh" "$dir" "$@")" \
      || die "sbatch refused the bounces' array job; cancel the others with: scancel $array $merge_id"
    array="${array%%;*}"
    echo "precompute-array: array job $array: the bounces of the $n shards, once $first_out is written"
    local direct_merge="$merge_id"
    merge_id="$(sbatch --parsable --job-name=hl-merge --dependency="afterok:$array" --kill-on-invalid-dep=yes \
                  --output="$dir/merge-bounces.out" --export=ALL,HAARLIGHT="$hl" \
                  "${common[@]}" "${merge_only[@]}" "$self" merge "$n" "$out" "$dir" bounce)"
    rc=$?
    merge_id="${merge_id%%;*}"
    [ "$rc" -eq 0 ] && [ -n "$merge_id" ] \
      || die "sbatch refused the last merge job (exit $rc); cancel the others with: scancel $array $direct_merge"
    echo "precompute-array: merge job $merge_id writes $out once the bounces have succeeded"
  fi
  [ "$wait" -eq 1 ] || return 0
  local state; state="$(wait_job "$merge_id" "$poll")"
  report_merge "$array" "$merge_id" "$out" "$dir" "$state"
}

[ $# -ge 1 ] || usage
mode="$1"; shift
case "$mode" in
  submit) submit "$@" ;;
  task) task "$@" ;;
  bounce-task) bounce_task "$@" ;;
  merge) merge "$@" ;;
  -h|--help) usage 0 ;;
  *) usage ;;
esac
