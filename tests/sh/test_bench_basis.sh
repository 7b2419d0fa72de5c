#!/usr/bin/env bash
# test_bench_basis.sh CASE - `haarlight bench-basis` end to end, tiny (a
# 16^2-cube, N = 16 transport of the bunny on its ground; cube faces of
# side 8 by default, 384 terms).
#   basis        under data/city.exr and the sky, --terms 25,200,400,all,
#                --bytes 20,60,100000 and order 20: basis.md, basis.csv,
#                basis.gp and basis.svg written (no temporary files left);
#                every whole row's error finite and in [0, 1), every cut
#                row's finite and >= 0; SH at all 400 terms no worse than
#                at 25 (linear); paraboloid Haar at all 512 terms, under
#                each selection, equal to the exact colours, and cube Haar
#                at all 384 to its own (the same rows and sums: errors
#                within 1e-6); rows cut to 100000 bytes (more than whole)
#                give the whole rows' errors; 20 bytes hold 4 paraboloid
#                entries and 60 hold 24; every whole row timed (ms > 0); the
#                summary line of each map printed, the summary tables in
#                basis.md.
#   cube_side    --cube-side 4 gives 96 cube terms, and its cube Haar at all
#                terms its own exact colours again; so does --cube-rows own,
#                and --continuous 8 adds both grids' errors against the
#                continuous reference to basis.md; on a C = 9 transport (no
#                power of two divides it) the cube bases are left out and
#                the rest, the plot included, is written.
#   bad_options  --sh-order 0 and 33, --terms 0, --vertices 0, --bytes 0
#                and x, --reps 0, --cube-rows exact, --continuous -1,
#                --cube-side 3 and 1024, --cube-side 32 on
#                C = 16, no -o and an unknown option exit 2 naming the
#                option; a missing transport or map exits 1 naming the
#                file, and leaves no basis files.
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
    --bytes 20,60,100000 --reps 2 -o "$tmp/out" >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" ||
    { rc=$?; cat "$tmp/stderr.txt"; fail "bench-basis exited $rc"; }
  cat "$tmp/stdout.txt"
  for f in basis.md basis.csv basis.gp; do [ -s "$tmp/out/$f" ] || fail "no $f"; done
  # the picture only where gnuplot is installed: the figures stand without it
  if command -v gnuplot >/dev/null; then [ -s "$tmp/out/basis.svg" ] || fail "no basis.svg"; fi
  ls "$tmp/out" | grep -q tmp && fail "temporary files left: $(ls "$tmp/out")"
  csv="$tmp/out/basis.csv"
  head -1 "$csv" | grep -qx "map,basis,terms,bytes,entries,l2,max,l2_unclamped,l2_own,ms" || fail "csv header: $(head -1 "$csv")"
  rows=$(awk -F, 'NR > 1 && $4 == "whole"' "$csv" | wc -l)
  cut=$(awk -F, 'NR > 1 && $4 != "whole"' "$csv" | wc -l)
  # 2 maps x (3 paraboloid Haar selections: 25 200 400 512; sh and
  # sh-nonlinear: 25 200 400; 3 cube Haar selections: 25 200 384), each
  # whole and at 3 budgets
  [ "$rows" -eq 54 ] || fail "expected 54 whole rows in basis.csv, got $rows"
  [ "$cut" -eq 162 ] || fail "expected 162 rows cut to bytes in basis.csv, got $cut"
  awk -F, 'NR > 1 { for (i = 6; i <= 9; i++) if (!($i >= 0 && $i < ($4 == "whole" ? 1 : 10))) { print "FAIL: " $0 ": column " i; bad = 1 }
                    if ($4 == "whole" && !($10 > 0)) { print "FAIL: " $0 ": not timed"; bad = 1 } }
           END { exit bad }' "$csv" || fail "errors out of range, not finite, or rows not timed"
  # rows cut to more bytes than they hold: the whole rows' errors
  awk -F, 'NR > 1 && $4 == "whole" { w[$1 "," $2 "," $3] = $6 }
           NR > 1 && $4 == 100000 { k = $1 "," $2 "," $3; if (!(k in w) || w[k] != $6) { print "FAIL: " $0 " against whole " w[k]; bad = 1 } }
           END { exit bad }' "$csv" || fail "rows cut to 100000 bytes differ from whole rows"
  e20=$(awk -F, '$2 == "haar" && $4 == 20 { print $5; exit }' "$csv")
  e60=$(awk -F, '$2 == "haar" && $4 == 60 { print $5; exit }' "$csv")
  c60=$(awk -F, '$2 == "cube-haar" && $4 == 60 { print $5; exit }' "$csv")
  echo "entries at 20 and 60 bytes: paraboloid $e20, $e60 (8 + 2 x 2 blocks + 2 K); cube at 60: $c60"
  [ "$e20" = 4 ] && [ "$e60" = 24 ] && [ "$c60" = 24 ] || fail "entries at 20/60 bytes: $e20 $e60 $c60, expected 4 24 24"
  for m in city sky; do
    s25=$(awk -F, -v m=$m '$1 == m && $2 == "sh" && $3 == 25 && $4 == "whole" { print $6 }' "$csv")
    s400=$(awk -F, -v m=$m '$1 == m && $2 == "sh" && $3 == 400 && $4 == "whole" { print $6 }' "$csv")
    hall=$(awk -F, -v m=$m '$1 == m && $2 ~ /^haar/ && $3 == 512 && $4 == "whole" { s += $6 + $7; n++ } END { print n == 3 ? s : "missing" }' "$csv")
    call=$(awk -F, -v m=$m '$1 == m && $2 ~ /^cube-haar/ && $3 == 384 && $4 == "whole" { s += $9; n++ } END { print n == 3 ? s : "missing" }' "$csv")
    echo "$m: sh L2 at 25 terms $s25, at 400 $s400; haar at all 512 terms: L2 + max $hall; cube Haar at all 384 against its own exact: $call (tolerance 1e-6)"
    awk -v a="$s400" -v b="$s25" 'BEGIN { exit !(a != "" && a <= b) }' || fail "$m: sh at 400 terms ($s400) above 25 ($s25)"
    awk -v a="$hall" 'BEGIN { exit !(a != "" && a <= 1e-6) }' || fail "$m: haar with every term is not the exact colours ($hall)"
    awk -v a="$call" 'BEGIN { exit !(a != "missing" && a <= 1e-6) }' || fail "$m: cube Haar with every term is not its exact colours ($call)"
    grep -q "^$m: at 200 terms, wavelet L2.*cube-face wavelets" "$tmp/stdout.txt" || fail "$m: no summary line"
  done
  for h in "## At 200 terms" "## Equal bytes, at 200 terms" "## Time of one lighting change" "## Every setting"; do
    grep -q "$h" "$tmp/out/basis.md" || fail "basis.md has no '$h'"
  done
  ;;
cube_side)
  scene
  "$bin" bench-basis "$tmp/s.hlt" --sky --vertices 16 --terms all --bytes 1000 --reps 1 --cube-side 4 -q -o "$tmp/out" \
    >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" || { rc=$?; cat "$tmp/stderr.txt"; fail "bench-basis exited $rc"; }
  n=$(awk -F, '$2 == "cube-haar" && $4 == "whole" { print $3 }' "$tmp/out/basis.csv")
  own=$(awk -F, '$2 == "cube-haar" && $4 == "whole" { print $9 }' "$tmp/out/basis.csv")
  echo "--cube-side 4: $n cube terms, at all of them against its own exact colours $own (tolerance 1e-6)"
  [ "$n" = 96 ] || fail "--cube-side 4 gives $n cube terms, expected 96"
  awk -v a="$own" 'BEGIN { exit !(a != "" && a <= 1e-6) }' || fail "cube side 4 with every term: $own"
  # the rows on the cube texels' own footprints, and both grids against
  # the continuous reference on 8 vertices
  "$bin" bench-basis "$tmp/s.hlt" --sky --vertices 16 --terms all --bytes 1000 --reps 1 --cube-rows own --continuous 8 -q \
    -o "$tmp/own" >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" || { cat "$tmp/stderr.txt"; fail "bench-basis --cube-rows own exited $?"; }
  own=$(awk -F, '$2 == "cube-haar" && $4 == "whole" { print $9 }' "$tmp/own/basis.csv")
  grid=$(grep "^| sky | [0-9.]*% | [0-9.]*% |$" "$tmp/own/basis.md")
  echo "--cube-rows own: cube Haar at every term against its own exact colours $own; against the continuous reference: $grid"
  awk -v a="$own" 'BEGIN { exit !(a != "" && a <= 1e-6) }' || fail "--cube-rows own with every term: $own"
  [ -n "$grid" ] || fail "no line of the grids against the continuous reference"
  # C = 9: no cube side divides it; the other bases and the plot go on
  "$bin" precompute "$data/bunny_lowres.obj" --ground -C 9 -N 16 -q -o "$tmp/c9.hlt" || fail "precompute -C 9"
  "$bin" bench-basis "$tmp/c9.hlt" --sky --vertices 16 --reps 1 -q -o "$tmp/c9" >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" ||
    { cat "$tmp/stderr.txt"; fail "bench-basis on C = 9 exited $?"; }
  grep -q ",cube-haar" "$tmp/c9/basis.csv" && fail "C = 9: cube rows written"
  grep -q ",haar-transport," "$tmp/c9/basis.csv" || fail "C = 9: no paraboloid rows"
  if command -v gnuplot >/dev/null; then [ -s "$tmp/c9/basis.svg" ] || fail "C = 9: no basis.svg"; fi
  echo "C = 9: the cube bases left out, the others and the plot written"
  ;;
bad_options)
  scene
  expect_exit 2 "--sh-order 0" "$tmp/s.hlt" --sky --sh-order 0 -o "$tmp/b"
  expect_exit 2 "--sh-order 33" "$tmp/s.hlt" --sky --sh-order 33 -o "$tmp/b"
  expect_exit 2 "--terms 0" "$tmp/s.hlt" --sky --terms 0 -o "$tmp/b"
  expect_exit 2 "--terms 25,x" "$tmp/s.hlt" --sky --terms 25,x -o "$tmp/b"
  expect_exit 2 "--vertices 0" "$tmp/s.hlt" --sky --vertices 0 -o "$tmp/b"
  expect_exit 2 "--bytes 0" "$tmp/s.hlt" --sky --bytes 0 -o "$tmp/b"
  expect_exit 2 "--bytes 100,x" "$tmp/s.hlt" --sky --bytes 100,x -o "$tmp/b"
  expect_exit 2 "--reps 0" "$tmp/s.hlt" --sky --reps 0 -o "$tmp/b"
  expect_exit 2 "--cube-rows exact: expected shared or own" "$tmp/s.hlt" --sky --cube-rows exact -o "$tmp/b"
  expect_exit 2 "--continuous -1" "$tmp/s.hlt" --sky --continuous -1 -o "$tmp/b"
  expect_exit 2 "--cube-side 3: expected a power of two" "$tmp/s.hlt" --sky --cube-side 3 -o "$tmp/b"
  expect_exit 2 "--cube-side 1024" "$tmp/s.hlt" --sky --cube-side 1024 -o "$tmp/b"
  expect_exit 2 "--cube-side 32: does not divide" "$tmp/s.hlt" --sky --cube-side 32 -o "$tmp/b"
  expect_exit 2 "-o DIR" "$tmp/s.hlt" --sky
  expect_exit 2 "unknown option --frobnicate" "$tmp/s.hlt" --frobnicate -o "$tmp/b"
  expect_exit 1 "$tmp/missing.hlt" "$tmp/missing.hlt" --sky -o "$tmp/b"
  expect_exit 1 "$tmp/missing.exr" "$tmp/s.hlt" --env "$tmp/missing.exr" -o "$tmp/b"
  for f in basis.md basis.csv basis.gp basis.svg; do [ -e "$tmp/b/$f" ] && fail "$f written after a failure"; done
  ls "$tmp/b" 2>/dev/null | grep -q tmp && fail "temporary files left after a failure"
  ;;
*)
  echo "unknown case ${1:-}"
  exit 2
  ;;
esac
[ "$fails" -eq 0 ] && echo "${1}: passed" || echo "${1}: $fails failure(s)"
exit $((fails > 0))
