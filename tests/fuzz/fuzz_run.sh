#!/usr/bin/env bash
# fuzz_run.sh - runs one libFuzzer target; used by ctest and run_long.sh.
#
#   fuzz_run.sh [--fresh] BIN SEEDS WORKDIR SECONDS [EXTRA_CORPUS...]
#       fuzzes BIN for SECONDS from WORKDIR/corpus, which starts as a copy
#       of SEEDS (--fresh: it and the crashes are emptied first; otherwise
#       it keeps what earlier runs found) and also reads EXTRA_CORPUS folders that exist. New
#       inputs go to WORKDIR/corpus only, never to SEEDS. Crashes, leaks,
#       timeouts and out-of-memory inputs are written to WORKDIR/crashes/.
#   fuzz_run.sh --replay BIN DIR
#       runs BIN once on every file in DIR (none: nothing to do).
#
# Prints "<target>: N executions in S s ..." and exits non-zero when the
# target failed, after printing the end of libFuzzer's log. HL_FUZZ_SEED
# fixes libFuzzer's seed (the ctest pass uses 1, so it runs the same
# inputs each time); without it the seed is random.
set -u

# A single allocation may reach the loaders' own bounds (an environment of
# 2^28 pixels is 3 GiB of floats, allocated before its rows are read);
# what is actually touched stays under the 2 GiB RSS limit.
limits=(-rss_limit_mb=2048 -malloc_limit_mb=4096 -timeout=10)
here="$(cd "$(dirname "$0")" && pwd)"
# lsan-<target>.supp, where it exists, suppresses leaks inside a
# third-party library that the target cannot free (see the file).
use_suppressions() {
  local supp="$here/lsan-$(basename "$1" | sed 's/^fuzz_//').supp"
  [ -f "$supp" ] && export LSAN_OPTIONS="suppressions=$supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
  return 0
}

if [ "${1:-}" = "--replay" ]; then
  bin="$2" dir="$3"
  use_suppressions "$bin"
  files=()
  if [ -d "$dir" ]; then
    while IFS= read -r -d '' f; do files+=("$f"); done < <(find "$dir" -type f ! -name '*.md' -print0 | sort -z)
  fi
  name="$(basename "$bin")"
  if [ "${#files[@]}" -eq 0 ]; then
    echo "$name: no regression inputs in $dir"
    exit 0
  fi
  "$bin" "${limits[@]}" "${files[@]}"
  rc=$?
  echo "$name: replayed ${#files[@]} regression inputs from $dir: exit $rc"
  exit $rc
fi

fresh=0
if [ "${1:-}" = "--fresh" ]; then fresh=1; shift; fi
if [ $# -lt 4 ]; then
  echo "usage: $0 [--fresh] BIN SEEDS WORKDIR SECONDS [EXTRA_CORPUS...] | --replay BIN DIR" >&2
  exit 2
fi
bin="$1" seeds="$2" work="$3" seconds="$4"
shift 4
name="$(basename "$bin")"
use_suppressions "$bin"

[ "$fresh" -eq 1 ] && rm -rf "$work/corpus" "$work/crashes"
mkdir -p "$work/corpus" "$work/crashes"
cp -n "$seeds"/* "$work/corpus/"
extra=()
for d in "$@"; do [ -d "$d" ] && extra+=("$d"); done

seed=()
[ -n "${HL_FUZZ_SEED:-}" ] && seed=(-seed="$HL_FUZZ_SEED")
log="$work/fuzz.log"
start=$(date +%s)
"$bin" "${limits[@]}" "${seed[@]}" -max_total_time="$seconds" -print_final_stats=1 \
  -artifact_prefix="$work/crashes/" "$work/corpus" "${extra[@]}" >"$log" 2>&1
rc=$?
elapsed=$(( $(date +%s) - start ))

runs="$(sed -n 's/^Done \([0-9]*\) runs in.*/\1/p' "$log" | tail -n 1)"
if [ -z "$runs" ]; then # stopped early: the last status line has the count
  runs="$(sed -n 's/^#\([0-9]*\).*/\1/p' "$log" | tail -n 1)"
fi
corpus="$(find "$work/corpus" -type f | wc -l)"
cov="$(grep -o 'cov: [0-9]*' "$log" | tail -n 1)"
echo "$name: ${runs:-0} executions in ${elapsed} s (${cov:-cov: ?}, corpus $corpus files), exit $rc"
if [ "$rc" -ne 0 ]; then
  echo "$name: FAILED; crashing inputs in $work/crashes/:"
  ls -l "$work/crashes/"
  echo "---- end of $log ----"
  tail -n 60 "$log"
fi
exit $rc
