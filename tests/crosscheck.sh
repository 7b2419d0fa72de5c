#!/usr/bin/env bash
# crosscheck.sh DEVICE [HAARLIGHT] - cross-checks one OpenCL device against
# the plain-C reference on the demo mesh: precompute files byte for byte
# (two parameter sets), every stage (`haarlight check`), and relit PLY
# colours. For devices the suite does not run on (it uses PoCL), e.g.
#   tests/crosscheck.sh cl:1:0          (see `haarlight devices`)
set -u
dev="${1:?usage: $0 DEVICE [HAARLIGHT]}"
bin="${2:-$(dirname "$0")/../build/haarlight}"
here="$(cd "$(dirname "$0")/.." && pwd)"
mesh="$here/data/bunny_lowres.obj" env="$here/data/city.exr"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fails=0
same() { if cmp -s "$1" "$2"; then echo "same: $3"; else echo "DIFFER: $3"; fails=$((fails + 1)); fi; }
"$bin" devices
for opts in "--ground" "--ground --quant linear8 -N 32 -C 48 --chunk 333"; do
  # shellcheck disable=SC2086
  "$bin" precompute "$mesh" $opts --device "$dev" -q -o "$tmp/d.hlt" || exit 1
  # shellcheck disable=SC2086
  "$bin" precompute "$mesh" $opts --device ref -q -o "$tmp/r.hlt" || exit 1
  same "$tmp/d.hlt" "$tmp/r.hlt" "precompute $opts"
  "$bin" check "$tmp/d.hlt" --env "$env" --device "$dev" || fails=$((fails + 1))
  "$bin" relight "$tmp/d.hlt" --env "$env" --device "$dev" -q -o "$tmp/d.ply"
  "$bin" relight "$tmp/d.hlt" --env "$env" --device ref -q -o "$tmp/r.ply"
  same "$tmp/d.ply" "$tmp/r.ply" "relight PLY ($opts)"
done
[ "$fails" -eq 0 ] && echo "crosscheck: $dev agrees with the reference" && exit 0
echo "crosscheck: $fails differences"
exit 1
