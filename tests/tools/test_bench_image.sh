#!/usr/bin/env bash
# test_bench_image.sh CASE - `haarlight bench --image` and
# `bench --surroundings` end to end, tiny (a 16^2-cube transport of the
# bunny on a coarse ground).
#   image        under the sky at M = 10 and all: each image error finite
#                and below 100%; L2 at M = all no larger than at M = 10 (all
#                terms hold all the lighting; 10 cannot hold more); the
#                popping under the turning map smaller at M = all than at
#                M = 10 (all terms change only with the map), and below the
#                exact pictures' own change; bench.md has both sections.
#   capture      with the example surroundings: the line names their 44
#                triangles and a rate above 0, bench.md has the table.
#   bad_options  --image-frames 0 and --image-size 4x4 exit 2 naming the
#                option; a missing surroundings file exits 1 naming it.
#   bounced      a file with one bounce and the direct one in one run: each
#                row names its reference (bench.csv, bench.md), the bounced
#                one's continuous column is not measured, its error at
#                M = all is finite and below 10%, bench.md gives the
#                reference's noise; --bounce-rays 0 and 3 exit 2 naming the
#                option; --image with the bounced file and two albedos in
#                one run exit 1 naming why.
# Env: HL_BIN (the binary), HL_TMP (scratch), HL_REPO_DATA (data/).
set -u
bin="${HL_BIN:?}"
data="${HL_REPO_DATA:?}"
tmp="${HL_TMP:-/tmp}/bench_image.$$"
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

scene() {
  "$bin" precompute "$data/bunny_lowres.obj" --ground --ground-res 16 -C 16 -N 16 -q -o "$tmp/s.hlt" ||
    { fail "precompute"; exit 1; }
}
quick=(--terms 10,all --select transport --no-ref-timing --reps 2 --vertices 16 --continuous 0 --no-banding)

case "${1:-}" in
image)
  scene
  "$bin" bench "$tmp/s.hlt" --sky "${quick[@]}" --image --image-frames 6 --image-size 96x72 -o "$tmp/out" \
    >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" || { cat "$tmp/stderr.txt"; fail "bench --image exited $?"; }
  grep "image L2\|turning" "$tmp/stdout.txt"
  # M: image L2 and H1, in %
  awk '/image L2/ { m=$7; sub(",", "", m); l2=$10; sub("%,", "", l2); h1=$12; sub("%", "", h1); print m, l2, h1 }' \
    "$tmp/stdout.txt" >"$tmp/img.txt"
  [ "$(wc -l <"$tmp/img.txt")" -eq 2 ] || fail "expected 2 image rows, got $(wc -l <"$tmp/img.txt")"
  awk '{ if (!($2 >= 0 && $2 < 100 && $3 >= 0 && $3 < 100)) { print "FAIL: M = " $1 ": image error " $2 " / " $3 "%"; bad=1 } }
       END { exit bad }' "$tmp/img.txt" || fail "image errors out of range"
  l10=$(awk '$1 == "10" { print $2 }' "$tmp/img.txt"); lall=$(awk '$1 == "all" { print $2 }' "$tmp/img.txt")
  awk -v a="$lall" -v b="$l10" 'BEGIN { exit !(a <= b) }' || fail "image L2 at M = all ($lall%) above M = 10 ($l10%)"
  # M: popping and the exact change, in %
  awk '/turning/ { m=$8; sub(":", "", m); p=$15; sub("%", "", p); o=$20; sub("%\\)", "", o); print m, p, o }' \
    "$tmp/stdout.txt" >"$tmp/pop.txt"
  [ "$(wc -l <"$tmp/pop.txt")" -eq 2 ] || fail "expected 2 popping rows, got $(wc -l <"$tmp/pop.txt")"
  p10=$(awk '$1 == "10" { print $2 }' "$tmp/pop.txt"); pall=$(awk '$1 == "all" { print $2 }' "$tmp/pop.txt")
  own=$(awk '$1 == "all" { print $3 }' "$tmp/pop.txt")
  echo "popping: M = 10 $p10%, M = all $pall%, the exact change $own%"
  awk -v a="$pall" -v b="$p10" 'BEGIN { exit !(a < b) }' || fail "popping at M = all ($pall%) not below M = 10 ($p10%)"
  awk -v a="$pall" -v b="$own" 'BEGIN { exit !(a < b && b > 0) }' || fail "popping at M = all ($pall%) not below the exact change ($own%)"
  grep -q "## Image-space errors" "$tmp/out/bench.md" || fail "bench.md has no image section"
  grep -q "## Temporal stability" "$tmp/out/bench.md" || fail "bench.md has no temporal section"
  ;;
capture)
  scene
  "$bin" bench "$tmp/s.hlt" --sky "${quick[@]}" --surroundings "$data/surroundings/lamp_orbit.gltf" -o "$tmp/out" \
    >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" || { cat "$tmp/stderr.txt"; fail "bench --surroundings exited $?"; }
  line=$(grep "new capture" "$tmp/stdout.txt")
  echo "$line"
  echo "$line" | grep -q "capture of 44 triangles" || fail "the capture line does not name 44 triangles"
  rate=$(echo "$line" | awk '{ print $3 }')
  awk -v r="$rate" 'BEGIN { exit !(r > 0) }' || fail "rate $rate"
  grep -q "## Lighting captured from surroundings" "$tmp/out/bench.md" || fail "bench.md has no capture table"
  echo "$line" | grep -q "from 1 point(s)" || fail "the capture line does not say one capture point"
  # more capture points: each change captures and relights once a point
  "$bin" bench "$tmp/s.hlt" --sky "${quick[@]}" --surroundings "$data/surroundings/lamp_orbit.gltf" --probes 4 \
    -o "$tmp/out4" >"$tmp/stdout4.txt" 2>"$tmp/stderr4.txt" || { cat "$tmp/stderr4.txt"; fail "bench --probes 4 exited $?"; }
  line4=$(grep "new capture" "$tmp/stdout4.txt")
  echo "$line4"
  echo "$line4" | grep -q "from 4 point(s)" || fail "--probes 4: the capture line does not say 4 points"
  "$bin" bench "$tmp/s.hlt" "${quick[@]}" --probes 4 -o "$tmp/o" >/dev/null 2>"$tmp/e5.txt"; rc=$?
  [ $rc -eq 2 ] && grep -q "probes needs --surroundings" "$tmp/e5.txt" || fail "--probes alone: exit $rc, $(cat "$tmp/e5.txt")"
  ;;
bad_options)
  scene
  "$bin" bench "$tmp/s.hlt" --image-frames 0 -o "$tmp/o" >/dev/null 2>"$tmp/e1.txt"; rc=$?
  [ $rc -eq 2 ] && grep -q "image-frames" "$tmp/e1.txt" || fail "--image-frames 0: exit $rc, $(cat "$tmp/e1.txt")"
  "$bin" bench "$tmp/s.hlt" --image-size 4x4 -o "$tmp/o" >/dev/null 2>"$tmp/e2.txt"; rc=$?
  [ $rc -eq 2 ] && grep -q "image-size" "$tmp/e2.txt" || fail "--image-size 4x4: exit $rc, $(cat "$tmp/e2.txt")"
  "$bin" bench "$tmp/s.hlt" "${quick[@]}" --surroundings "$tmp/nosuch.gltf" -o "$tmp/o" >/dev/null 2>"$tmp/e3.txt"; rc=$?
  [ $rc -eq 1 ] && grep -q "nosuch.gltf" "$tmp/e3.txt" || fail "missing surroundings: exit $rc, $(cat "$tmp/e3.txt")"
  ;;
bounced)
  scene
  "$bin" precompute "$data/bunny_lowres.obj" --ground --ground-res 16 -C 16 -N 16 --bounces 1 -q -o "$tmp/b.hlt" ||
    { fail "precompute --bounces 1"; exit 1; }
  "$bin" bench "$tmp/s.hlt" "$tmp/b.hlt" --sky --terms all --select transport --no-ref-timing --reps 2 --vertices 64 \
    --continuous 4 --no-banding --bounce-rays 64 -o "$tmp/out" >"$tmp/stdout.txt" 2>"$tmp/stderr.txt" ||
    { cat "$tmp/stderr.txt"; fail "bench of a bounced file exited $?"; }
  grep "bounced" "$tmp/stderr.txt"
  # file, l2_exact and l2_continuous (columns before the quoted reference, which holds a comma)
  awk -F, 'NR > 1 { print $1 "|" $12 "|" $14 }' "$tmp/out/bench.csv" | tee "$tmp/rows.txt"
  grep -q '^s.hlt,.*,"exact (direct)",0$' "$tmp/out/bench.csv" || fail "the direct file's row does not name the direct reference"
  grep -q '^b.hlt,.*,"exact (direct + 1 bounce, 64 rays)",[0-9.e-]*$' "$tmp/out/bench.csv" ||
    fail "the bounced file's row does not name its reference"
  grep -q '^b.hlt|.*|nan$' "$tmp/rows.txt" || fail "the bounced file has a continuous error (that reference is direct only)"
  l2=$(awk -F'|' '$1 == "b.hlt" { print $2 }' "$tmp/rows.txt")
  awk -v e="$l2" 'BEGIN { exit !(e >= 0 && e < 0.1) }' || fail "the bounced file's L2 against its reference: $l2"
  grep -q "b.hlt against exact (direct + 1 bounce, 64 rays)" "$tmp/out/bench.md" || fail "bench.md does not name the reference"
  grep -q "^| 1 | .*% (bound .*%) |" "$tmp/out/bench.md" || fail "bench.md does not give the reference's noise"
  for k in 0 3 x; do
    "$bin" bench "$tmp/b.hlt" --bounce-rays $k -o "$tmp/o" >/dev/null 2>"$tmp/e.txt"; rc=$?
    [ $rc -eq 2 ] && grep -q -- "--bounce-rays $k" "$tmp/e.txt" || fail "--bounce-rays $k: exit $rc, $(cat "$tmp/e.txt")"
  done
  "$bin" bench "$tmp/b.hlt" --sky "${quick[@]}" --image -o "$tmp/o" >/dev/null 2>"$tmp/e.txt"; rc=$?
  [ $rc -eq 1 ] && grep -q -- "--image: .*b.hlt has 1 bounces" "$tmp/e.txt" || fail "--image with a bounced file: exit $rc, $(cat "$tmp/e.txt")"
  "$bin" precompute "$data/bunny_lowres.obj" --ground --ground-res 16 -C 16 -N 16 --ground-albedo 0.8,0.15,0.1 -q -o "$tmp/r.hlt" ||
    fail "precompute --ground-albedo"
  "$bin" bench "$tmp/s.hlt" "$tmp/r.hlt" --sky "${quick[@]}" -o "$tmp/o" >/dev/null 2>"$tmp/e.txt"; rc=$?
  [ $rc -eq 1 ] && grep -q "not the same albedo" "$tmp/e.txt" || fail "two albedos: exit $rc, $(cat "$tmp/e.txt")"
  ;;
*) echo "usage: $0 image|capture|bad_options|bounced" >&2; exit 2 ;;
esac
[ $fails -eq 0 ] || exit 1
echo "passed"
