#!/usr/bin/env bash
# test_bench_basis.sh CASE - `haarlight bench-basis` end to end, tiny (a
# 16^2-cube, N = 16 transport of the bunny on its ground).
#   basis        under data/city.exr and the sky, --terms 25,200,400,all
#                and order 20: basis.md and basis.csv written (no temporary
#                files left); every error finite and in [0, 1); SH at all
#                400 terms no worse than at 25 (linear); Haar at all 512
#                terms, under each selection, equal to the exact colours
#                (the same rows and sums: errors within 1e-6); the summary
#                line of each map printed.
#   bad_options  --sh-order 0 and 33, --terms 0, --vertices 0, no -o and an
#                unknown option exit 2 naming the option; a missing
#                transport or map exits 1 naming the file, and leaves no
#                basis files.
# Env: HL_BIN (the binary), HL_TMP (scratch), HL_REPO_DATA (data/).
set -u
bin="${HL_BIN:?}"
data="${HL_REPO_DATA:?}"
tmp="${HL_TMP:-/tmp}/bench_basis.$$"
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

scene() {
  "$bin" precompute "$data/bunny_lowres.obj" --ground -C 16 -N 16 -q -o "$tmp/s.hlt" ||
    { fail "precompute"; exit 1; }
}

# expect_exit CODE TEXT ARGS...: the command exits CODE and its stderr names TEXT.
expect_exit() {
  local code="$1" text="$2"
  shift 2
  "$bin" bench-basis "$@" >"$tmp/o.txt" 2>"$tmp/e.txt"
  local rc=$?
  [ "$rc" -eq "$code" ] || fail "bench-basis $*: exit $rc, expected $code"
  grep -q -- "$text" "$tmp/e.txt" || { fail "bench-basis $*: stderr does not name '$text'"; cat "$tmp/e.txt"; }
}

case "${1:-}" in
basis)
  scene
  "$bin" bench-basis "$tmp/s.hlt" --env "$data/city.exr" --sky --vertices 64 --terms 25,200,400,all \
    -o "$tmp/out" >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" || { cat "$tmp/stderr.txt"; fail "bench-basis exited $?"; }
  cat "$tmp/stdout.txt"
  [ -s "$tmp/out/basis.md" ] || fail "no basis.md"
  [ -s "$tmp/out/basis.csv" ] || fail "no basis.csv"
  ls "$tmp/out" | grep -q tmp && fail "temporary files left: $(ls "$tmp/out")"
  rows=$(tail -n +2 "$tmp/out/basis.csv" | wc -l)
  # 2 maps x (3 Haar selections: 25 200 400 512; sh and sh-nonlinear: 25 200 400)
  [ "$rows" -eq 36 ] || fail "expected 36 rows in basis.csv, got $rows"
  awk -F, 'NR > 1 { for (i = 4; i <= 6; i++) if (!($i >= 0 && $i < 1)) { print "FAIL: " $0 ": column " i " out of [0, 1)"; bad = 1 } }
           END { exit bad }' "$tmp/out/basis.csv" || fail "errors out of [0, 1) or not finite"
  for m in city sky; do
    s25=$(awk -F, -v m=$m '$1 == m && $2 == "sh" && $3 == 25 { print $4 }' "$tmp/out/basis.csv")
    s400=$(awk -F, -v m=$m '$1 == m && $2 == "sh" && $3 == 400 { print $4 }' "$tmp/out/basis.csv")
    hall=$(awk -F, -v m=$m '$1 == m && $2 ~ /^haar/ && $3 == 512 { s += $4 + $5 } END { print s }' "$tmp/out/basis.csv")
    echo "$m: sh L2 at 25 terms $s25, at 400 $s400; haar at all 512 terms: L2 + max $hall (tolerance 1e-6)"
    awk -v a="$s400" -v b="$s25" 'BEGIN { exit !(a != "" && a <= b) }' || fail "$m: sh at 400 terms ($s400) above 25 ($s25)"
    awk -v a="$hall" 'BEGIN { exit !(a != "" && a <= 1e-6) }' || fail "$m: haar with every term is not the exact colours ($hall)"
    grep -q "^$m: at 200 terms, wavelet L2" "$tmp/stdout.txt" || fail "$m: no summary line"
  done
  grep -q "## At 200 terms" "$tmp/out/basis.md" || fail "basis.md has no summary at 200 terms"
  ;;
bad_options)
  scene
  expect_exit 2 "--sh-order 0" "$tmp/s.hlt" --sky --sh-order 0 -o "$tmp/b"
  expect_exit 2 "--sh-order 33" "$tmp/s.hlt" --sky --sh-order 33 -o "$tmp/b"
  expect_exit 2 "--terms 0" "$tmp/s.hlt" --sky --terms 0 -o "$tmp/b"
  expect_exit 2 "--terms 25,x" "$tmp/s.hlt" --sky --terms 25,x -o "$tmp/b"
  expect_exit 2 "--vertices 0" "$tmp/s.hlt" --sky --vertices 0 -o "$tmp/b"
  expect_exit 2 "-o DIR" "$tmp/s.hlt" --sky
  expect_exit 2 "unknown option --frobnicate" "$tmp/s.hlt" --frobnicate -o "$tmp/b"
  expect_exit 1 "$tmp/missing.hlt" "$tmp/missing.hlt" --sky -o "$tmp/b"
  expect_exit 1 "$tmp/missing.exr" "$tmp/s.hlt" --env "$tmp/missing.exr" -o "$tmp/b"
  [ -e "$tmp/b/basis.md" ] || [ -e "$tmp/b/basis.csv" ] && fail "basis files written after a failure"
  ls "$tmp/b" 2>/dev/null | grep -q tmp && fail "temporary files left after a failure"
  ;;
*)
  echo "unknown case ${1:-}"
  exit 2
  ;;
esac
[ "$fails" -eq 0 ] && echo "${1}: passed" || echo "${1}: $fails failure(s)"
exit $((fails > 0))
