#!/usr/bin/env bash
# run_long.sh [SECONDS] [TARGET...] - the long fuzz run.
#
# Configures and builds build-fuzz/ (clang, HL_FUZZ=ON) when needed, then
# fuzzes each target (transport, mesh, env; all by default) for SECONDS
# (default 600) with a random seed. Each target's corpus grows across runs
# in build-fuzz/fuzz-long/<target>/corpus, seeded from tests/fuzz/corpus;
# crashing inputs go to build-fuzz/fuzz-long/<target>/crashes/. Prints the
# executions per target and exits non-zero when any target failed.
#
# Env: HL_FUZZ_JOBS (build jobs, default 2).
set -u
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build="$root/build-fuzz"
seconds="${1:-600}"
[ $# -gt 0 ] && shift
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(transport mesh env)
case "$seconds" in ''|*[!0-9]*) echo "usage: $0 [SECONDS] [transport|mesh|env ...]" >&2; exit 2 ;; esac

if [ ! -f "$build/CMakeCache.txt" ]; then
  CC="${CC:-clang}" cmake -S "$root" -B "$build" -DHL_FUZZ=ON -DHL_WITH_VIEWER=OFF \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo || exit 1
fi
bins=()
for t in "${targets[@]}"; do bins+=("fuzz_$t"); done
cmake --build "$build" -j"${HL_FUZZ_JOBS:-2}" --target "${bins[@]}" || exit 1

out="$build/fuzz-long"
mkdir -p "$out/tmp"
export HL_FUZZ_TMP="$out/tmp"
summary=()
failed=0
for t in "${targets[@]}"; do
  bash "$here/fuzz_run.sh" "$build/tests/fuzz/fuzz_$t" "$here/corpus/$t" "$out/$t" "$seconds" \
    "$here/regress/$t" >"$out/$t.txt"
  [ $? -eq 0 ] || failed=1
  cat "$out/$t.txt"
  summary+=("$(head -n 1 "$out/$t.txt")")
done
echo
echo "long fuzz run, $seconds s per target (crashes in $out/<target>/crashes/):"
printf '  %s\n' "${summary[@]}"
exit $failed
