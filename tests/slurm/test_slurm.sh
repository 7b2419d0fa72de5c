#!/usr/bin/env bash
# test_slurm.sh CASE - the users' Slurm array-job script,
# host/cli/slurm/precompute-array.sh.
#   array  on a real one-node Slurm cluster started on this machine
#          (cluster.sh beside this script: munged, slurmctld and slurmd
#          from Debian's slurm-wlm and munge, which setup.sh installs for
#          the tests), four shards as an array job and their merge as a
#          job depending on it must equal one ordinary run byte for byte.
#          Skips (77), saying why, without root, without Slurm or MUNGE,
#          or where haarlight has no precompute --shard or merge. First,
#          on the same cluster, shards that fail: the merge job is
#          cancelled and submit --wait exits 1 naming the failed tasks.
#   requeue the same with two shards, shard 0 requeued by Slurm part-way
#          (scontrol requeue): its task runs again, resumes its shard's
#          .partial from a vertex past 0, and the merge still equals one
#          run. Skips as array does.
#   usage  the script's refusals, which need no cluster: each exits 2 with
#          a message naming the problem, before anything is submitted.
# Env: HL_BIN (the binary), HL_REPO_DATA (data/), HL_SRC (the source tree).
set -u
bin="${HL_BIN:?}"
data="${HL_REPO_DATA:?}"
src="${HL_SRC:-$(cd "$(dirname "$0")/../.." && pwd)}"
here="$src/tests/slurm"
script="$src/host/cli/slurm/precompute-array.sh"

# four shards: more than the node's two CPUs, so tasks also wait their
# turn, and an uneven split of the mesh's vertices (1839 = 4 * 459 + 3)
SHARDS=4
MESH="$data/bunny_lowres.obj"
# small maps keep each shard to a second or so; the point is the split and
# the join, which these exercise as any size would
OPTS=(-C 16 -N 16 -q)
# the requeue case: two shards (both run at once), each long enough (about
# 3 s here: the ground, 9 rays a texel, one thread as --cpus-per-task=1
# makes the script pass --threads 1) that Slurm can requeue shard 0
# part-way; small chunks (about 35 ms each), so that part is kept. Not
# quiet: the task's log must say where it resumed. The single run to
# compare with uses every core (threads do not change the bytes).
RQ_SHARDS=2
RQ_OPTS=(--ground -C 16 -N 16 --supersample 3 --chunk 64)
# the whole submit-and-wait: it takes a few seconds here (polled every
# second); three minutes means something is stuck, not slow
JOB_TIMEOUT_S=180

skip() { echo "SKIP: $*"; exit 77; }
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

# in /tmp, not $TMPDIR: munged wants every folder above its socket
# searchable by all, which /tmp is and a private TMPDIR may not be
tmp="$(mktemp -d /tmp/hl-slurm.XXXXXX)" || { echo "FAIL: no temporary folder in /tmp"; exit 1; }
child=""
cleanup() {
  [ -n "$child" ] && kill -TERM "$child" 2>/dev/null
  [ -d "$tmp/cluster" ] && "$here/cluster.sh" stop "$tmp/cluster"
  rm -rf "$tmp"
}
trap cleanup EXIT
trap 'exit 1' INT TERM

# refuses WHAT PART -- ARGS...: the script with ARGS exits 2 and says PART
refuses() {
  local what="$1" part="$2"; shift 3
  "$@" >"$tmp/out.txt" 2>"$tmp/err.txt"
  local rc=$?
  echo "$what: exit $rc: $(head -c 200 "$tmp/err.txt" | tr '\n' ' ')"
  [ "$rc" -eq 2 ] || fail "$what: exit $rc, expected 2"
  grep -q -- "$part" "$tmp/err.txt" || fail "$what: the message lacks '$part'"
}

case_usage() {
  local hl=(env HAARLIGHT="$bin" "$script")
  refuses "no arguments" "precompute-array.sh submit" -- "${hl[@]}"
  refuses "unknown mode" "precompute-array.sh submit" -- "${hl[@]}" frobnicate
  refuses "N of 0" "N must be a whole number" -- "${hl[@]}" submit 0 "$MESH" "$tmp/o.hlt"
  refuses "N not a number" "not '4x'" -- "${hl[@]}" submit 4x "$MESH" "$tmp/o.hlt"
  refuses "--poll of 0" "--poll 0: expected whole seconds" -- "${hl[@]}" submit --wait --poll 0 4 "$MESH" "$tmp/o.hlt"
  refuses "-o given" "option -o is set by this script" -- "${hl[@]}" submit 4 "$MESH" "$tmp/o.hlt" -o x.hlt
  refuses "--shard given" "option --shard is set by this script" -- "${hl[@]}" submit 4 "$MESH" "$tmp/o.hlt" --shard 1/2
  refuses "missing mesh" "cannot read the mesh $tmp/none.obj" -- "${hl[@]}" submit 4 "$tmp/none.obj" "$tmp/o.hlt"
  refuses "missing folder" "the folder of $tmp/no/o.hlt does not exist" -- "${hl[@]}" submit 4 "$MESH" "$tmp/no/o.hlt"
  refuses "no haarlight" "HAARLIGHT=$tmp/none is not an executable" -- \
    env HAARLIGHT="$tmp/none" "$script" submit 4 "$MESH" "$tmp/o.hlt"
  # a program without precompute --shard (true prints no help at all)
  refuses "old haarlight" "has no precompute --shard" -- \
    env HAARLIGHT="$(type -P true)" "$script" submit 4 "$MESH" "$tmp/o.hlt"
  refuses "task outside an array" "SLURM_ARRAY_TASK_ID is not set" -- \
    env -u SLURM_ARRAY_TASK_ID HAARLIGHT="$bin" "$script" task 4 "$MESH" "$tmp"
  refuses "task beyond N" "array task 4 is outside 0..3" -- \
    env SLURM_ARRAY_TASK_ID=4 HAARLIGHT="$bin" "$script" task 4 "$MESH" "$tmp"
  [ -e "$tmp/o.hlt.shards" ] && fail "a refused submit made $tmp/o.hlt.shards"
  return 0
}

# start_cluster: the skips, then a private cluster in $tmp/cluster, its
# SLURM_CONF exported for the client commands
start_cluster() {
  local c
  for c in munged slurmctld slurmd sbatch scontrol squeue sinfo scancel; do
    command -v "$c" >/dev/null 2>&1 || skip "$c not found (install slurm-wlm and munge: ./setup.sh test does)"
  done
  [ "$(id -u)" -eq 0 ] || skip "slurmd must run as root to start jobs; this runs as $(id -un)"
  "$bin" precompute --help 2>&1 | grep -q -- '--shard' || skip "haarlight precompute has no --shard yet"
  "$bin" merge --help >/dev/null 2>&1 || skip "haarlight has no merge yet"
  [ -r "$MESH" ] || { echo "FAIL: cannot read $MESH"; exit 1; }
  mkdir -p "$tmp/cluster" "$tmp/out"
  # munged's socket must be reachable by every user through all its folders
  chmod 711 "$tmp"
  "$here/cluster.sh" start "$tmp/cluster" || { echo "FAIL: the cluster did not start"; exit 1; }
  # shellcheck disable=SC1091
  . "$tmp/cluster/env"
}

# submit N OPTION...: the users' script submits N shards (with the sbatch
# options in the array sbatch_opts, as -s OPTION pairs) and the merge of
# $tmp/out/sharded.hlt and waits, in the background (a signal to this
# script is then handled at once; $child is its pid). The jobs carry the
# cluster's mark, so that its stop ends any left behind.
submit() {
  local n="$1"; shift
  submit_ms=$(( $(date +%s%N) / 1000000 ))
  env "$(cat "$tmp/cluster/mark")" HAARLIGHT="$bin" timeout "$JOB_TIMEOUT_S" \
    "$script" submit "${sbatch_opts[@]}" --wait --poll 1 "$n" "$MESH" "$tmp/out/sharded.hlt" "$@" &
  child=$!
}

# finish N: waits for submit's command, shows the jobs' logs, fails unless
# all succeeded and every shard ran as its own array task
finish() {
  local n="$1" rc took_ms c i
  wait "$child"
  rc=$?
  child=""
  took_ms=$(( $(date +%s%N) / 1000000 - submit_ms ))
  for c in "$tmp/out/sharded.hlt.shards"/*.out; do
    [ -f "$c" ] && { echo "--- $(basename "$c")"; tr '\r' '\n' <"$c" | grep -v '^ *$'; }
  done
  [ "$rc" -eq 124 ] && { echo "FAIL: the jobs did not end within ${JOB_TIMEOUT_S} s"; squeue; exit 1; }
  [ "$rc" -eq 0 ] || { echo "FAIL: the array job or the merge failed (exit $rc)"; exit 1; }
  echo "slurm: $n shards and their merge took $((took_ms / 1000)).$(printf %03d $((took_ms % 1000))) s from submission"
  for ((i = 0; i < n; i++)); do
    grep -q "shard $i/$n" "$tmp/out/sharded.hlt.shards/task-$i.out" 2>/dev/null \
      || fail "no log of array task $i"
  done
}

# same_as_one_run N OPTION...: the merged file must be the bytes of one
# ordinary run with the same options
same_as_one_run() {
  local n="$1"; shift
  "$bin" precompute "$MESH" -o "$tmp/out/single.hlt" -q "$@" \
    || { echo "FAIL: the single run failed"; exit 1; }
  echo "compared: $n shards merged ($(stat -c %s "$tmp/out/sharded.hlt") bytes) with one run" \
       "($(stat -c %s "$tmp/out/single.hlt") bytes) of $(basename "$MESH") $*"
  if cmp "$tmp/out/sharded.hlt" "$tmp/out/single.hlt"; then
    echo "identical: sha256 $(sha256sum <"$tmp/out/single.hlt" | cut -c1-16)..."
  else
    fail "the merged shards differ from one run"
  fi
}

# a failed shard: the merge job is cancelled, submit --wait exits 1 naming
# the failed tasks, and nothing is written (a mesh with no faces is
# readable, so submit takes it, and refused by every task)
failed_shards() {
  local rc
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\n' >"$tmp/out/nofaces.obj"
  env "$(cat "$tmp/cluster/mark")" HAARLIGHT="$bin" timeout "$JOB_TIMEOUT_S" \
    "$script" submit --wait --poll 1 2 "$tmp/out/nofaces.obj" "$tmp/out/failed.hlt" -q \
    >"$tmp/failed.txt" 2>&1 &
  child=$!
  wait "$child"
  rc=$?
  child=""
  echo "failed shards: exit $rc:"
  cat "$tmp/failed.txt"
  [ "$rc" -eq 1 ] || fail "submit --wait with failed shards: exit $rc, expected 1"
  grep -q "merge job .* ended CANCELLED" "$tmp/failed.txt" || fail "the merge job was not reported cancelled"
  [ "$(grep -c 'JobState=FAILED' "$tmp/failed.txt")" -eq 2 ] || fail "the two failed tasks were not listed"
  [ -e "$tmp/out/failed.hlt" ] && fail "a merge of failed shards wrote $tmp/out/failed.hlt"
  return 0
}

sbatch_opts=()
case_array() {
  start_cluster
  failed_shards
  submit "$SHARDS" "${OPTS[@]}"
  finish "$SHARDS"
  same_as_one_run "$SHARDS" "${OPTS[@]}"
}

# the bounces: two phases (the direct rows' shards and merge, then each
# shard's bounces from them and their merge), a coloured ground so that
# three planes of rows are merged; the result must be one run's bytes
# (which start from the direct rows' floats, so the shards' must too)
BOUNCE_OPTS=(--ground --ground-res 12 --ground-albedo 0.8,0.2,0.1 -C 16 -N 16 --bounces 2 --bounce-rays 16 -q)
case_bounces() {
  start_cluster
  submit 3 "${BOUNCE_OPTS[@]}"
  finish 3
  local i
  for ((i = 0; i < 3; i++)); do
    grep -q "bounce shard $i/3" "$tmp/out/sharded.hlt.shards/bounce-$i.out" 2>/dev/null \
      || fail "no log of the bounces' array task $i"
  done
  # the bounces start from the direct rows' floats, merged from the shards'
  [ -f "$tmp/out/sharded.hlt.shards/direct.hlt.values" ] || fail "no direct.hlt.values beside the merged direct rows"
  same_as_one_run 3 "${BOUNCE_OPTS[@]}"
}

# grows FILE: waits until FILE exists and has grown twice after that (its
# header, then at least one chunk of rows), up to JOB_TIMEOUT_S
grows() {
  local sizes=() now i=0
  while [ "$i" -lt $(( JOB_TIMEOUT_S * 10 )) ]; do
    now="$(stat -c %s "$1" 2>/dev/null || echo 0)"
    if [ "$now" -gt 0 ] && { [ "${#sizes[@]}" -eq 0 ] || [ "$now" -gt "${sizes[-1]}" ]; }; then
      sizes+=("$now")
      [ "${#sizes[@]}" -ge 3 ] && { echo "${sizes[*]}"; return 0; }
    fi
    sleep 0.1
    i=$((i + 1))
  done
  return 1
}

case_requeue() {
  start_cluster
  sbatch_opts=(-s --cpus-per-task=1)
  submit "$RQ_SHARDS" "${RQ_OPTS[@]}"
  local partial="$tmp/out/sharded.hlt.shards/shard-0-of-$RQ_SHARDS.hls.partial" sizes array
  sizes="$(grows "$partial")" || { echo "FAIL: $partial never grew"; exit 1; }
  array="$(squeue -h -n hl-precompute -o %F | head -n 1)"
  echo "requeue: array task ${array}_0 while its .partial grows (sizes seen: $sizes bytes)"
  scontrol requeue "${array}_0" || { echo "FAIL: scontrol requeue ${array}_0 refused"; exit 1; }
  finish "$RQ_SHARDS"
  local log="$tmp/out/sharded.hlt.shards/task-0.out" at
  grep -q "restart 1" "$log" || fail "task 0 did not run a second time"
  grep -q "interrupted" "$log" || fail "task 0's first run was not interrupted"
  at="$(grep -o 'resuming .* at vertex [0-9]*' "$log" | grep -o '[0-9]*$')"
  echo "requeued task 0 resumed at vertex ${at:-none}"
  if [ -z "$at" ] || [ "$at" -eq 0 ]; then
    fail "the requeued task did not resume its shard from a kept vertex"
  fi
  same_as_one_run "$RQ_SHARDS" "${RQ_OPTS[@]}"
}

case "${1:-}" in
  usage) case_usage ;;
  array) case_array ;;
  requeue) case_requeue ;;
  bounces) case_bounces ;;
  *) echo "usage: $0 usage|array|requeue|bounces" >&2; exit 2 ;;
esac
[ "$fails" -eq 0 ] || { echo "$fails failed"; exit 1; }
echo "PASS"
