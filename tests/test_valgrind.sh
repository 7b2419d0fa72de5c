#!/usr/bin/env bash
# test_valgrind.sh - memcheck over a small scene: precompute and relight on
# the OpenCL device (PoCL) and on the plain-C reference. Any error in the
# project's code, or any definite leak, fails; tests/valgrind.supp lists
# the one false positive outside it (glibc's loader).
# PoCL compiles a kernel with LLVM the first time it meets it, and that
# compiler loses memory of its own; so the OpenCL runs go once outside
# valgrind first, filling PoCL's kernel cache, and memcheck then sees the
# project with a warm cache whatever state the machine's cache was in.
# Valgrind's CPU may lack features of the real one (AVX-512: PoCL's device
# is pthread-skylake-avx512 outside and pthread-haswell under valgrind on
# an AVX-512 host), and PoCL caches kernels per CPU; so the same runs go
# once more under valgrind without checking, to fill that CPU's cache
# (quick where the two CPUs are the same).
# Env: HL_BIN, HL_TMP, HL_SRC. Exit 77 (skip) without valgrind.
set -u
bin="${HL_BIN:?}"
src="${HL_SRC:?}"
tmp="${HL_TMP:-/tmp}/valgrind.$$"
command -v valgrind >/dev/null || { echo "SKIP: valgrind is not installed"; exit 77; }
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n' >"$tmp/tet.obj"
vg=(valgrind --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite
    --show-leak-kinds=definite --suppressions="$src/tests/valgrind.supp" -q)
fails=0
# the OpenCL runs, each command prefixed by "$@" (nothing, or valgrind)
warm() {
  "$@" "$bin" precompute "$tmp/tet.obj" --ground --ground-res 8 -N 16 -C 16 -o "$tmp/warm.hlt" -q &&
    "$@" "$bin" relight "$tmp/warm.hlt" --sky --size 64x48 -o "$tmp/warm.png" -q
}
warm || { echo "FAIL: warming PoCL's kernel cache: a run failed outside valgrind"; exit 1; }
warm valgrind -q --leak-check=no 2>/dev/null || { echo "FAIL: warming PoCL's kernel cache: a run failed under valgrind"; exit 1; }
echo "PoCL kernel cache warmed outside valgrind and under it, unchecked (${POCL_CACHE_DIR:-its default folder})"
run() {
  local name="$1"; shift
  "${vg[@]}" "$bin" "$@" -q 2>"$tmp/$name.log"
  local rc=$?
  echo "$name: exit $rc, $(grep -c '^==[0-9]*== [A-Z]' "$tmp/$name.log") memcheck lines"
  if [ "$rc" -ne 0 ]; then cat "$tmp/$name.log"; fails=$((fails + 1)); fi
}
for dev in cl ref; do
  run "precompute_$dev" precompute "$tmp/tet.obj" --ground --ground-res 8 -N 16 -C 16 --device "$dev" -o "$tmp/$dev.hlt"
  run "relight_png_$dev" relight "$tmp/$dev.hlt" --sky --device "$dev" --size 64x48 -o "$tmp/$dev.png"
  run "relight_ply_$dev" relight "$tmp/$dev.hlt" --sky --terms all --device "$dev" -o "$tmp/$dev.ply"
done
cmp "$tmp/cl.hlt" "$tmp/ref.hlt" || { echo "FAIL: OpenCL and reference files differ under valgrind"; fails=$((fails + 1)); }
[ "$fails" -eq 0 ] && echo "valgrind: 6 runs clean" && exit 0
echo "valgrind: $fails runs failed"
exit 1
