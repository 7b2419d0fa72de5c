#!/usr/bin/env bash
# gpu.sh DEVICE [OTHER] - one report of an OpenCL device: the crosscheck
# against the plain-C reference, the test suite on it, and the relight and
# dynamic benches, each bench run alternating with OTHER in the same run
# when one is named (the same machine's PoCL beside its GPU, say).
#
#   tests/gpu.sh cl:0:0 cl:1:0        (see `haarlight devices`)
#   tests/gpu.sh cl:0:0/gpu cl:0:0    a device in the GPU shape against itself
#                                     in its own (HL_DEVICE_SHAPE)
#
# A device is cl:P:D, optionally /cpu or /gpu to force the kernels' shape.
# Writes $GPU_OUT/report.md (default gpu-report/) and each step's log beside
# it (7 files at most). Env: GPU_WORK (a folder to keep the transports and
# bench outputs in; default a temporary one), HL_BIN (default
# build/haarlight), HL_BUILD (the CTest build folder,
# default build), HL_SHARED_DATA (default ../shared/data), GPU_PARTS (the steps,
# default "crosscheck suite bunny dragon dynamic"), GPU_ROUNDS (bench runs a
# device and mesh, default 3). Exit status 1 when the crosscheck or the suite
# failed; the benches report figures and judge nothing.
set -u
here="$(cd "$(dirname "$0")/.." && pwd)"
dev="${1:?usage: $0 DEVICE [OTHER]   (DEVICE: cl:P:D or cl:P:D/gpu; see haarlight devices)}"
other="${2:-}"
bin="${HL_BIN:-$here/build/haarlight}"
build="${HL_BUILD:-$here/build}"
shared="${HL_SHARED_DATA:-$here/../shared/data}"
out="${GPU_OUT:-gpu-report}"
parts="${GPU_PARTS:-crosscheck suite bunny dragon dynamic}"
rounds="${GPU_ROUNDS:-3}"
mkdir -p "$out" || exit 2
out="$(cd "$out" && pwd)"
rep="$out/report.md"
# transports and bench folders in a scratch folder (GPU_WORK keeps them):
# $GPU_OUT gets the report and its logs only, 7 files
if [ -n "${GPU_WORK:-}" ]; then work="$GPU_WORK"; mkdir -p "$work" || exit 2
else work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT; fi
[ -x "$bin" ] || { echo "gpu.sh: $bin: no haarlight binary (set HL_BIN)" >&2; exit 2; }
for d in "$dev" ${other:+"$other"}; do
  [[ "$d" =~ ^cl:[0-9]+:[0-9]+(/(cpu|gpu))?$ ]] || { echo "gpu.sh: $d: expected cl:P:D, cl:P:D/cpu or cl:P:D/gpu" >&2; exit 2; }
done
has() { [[ " $parts " == *" $1 "* ]]; }
t_start=$(date +%s)
say() { echo "gpu.sh: $(($(date +%s) - t_start)) s: $*" >&2; }

# run SPEC CMD ARGS...: haarlight CMD on SPEC's device, in its shape if one is named
run() {
  local spec="$1"; shift
  local d="${spec%%/*}" shape=""
  [[ "$spec" == */* ]] && shape="${spec##*/}"
  local cmd="$1"; shift
  if [ -n "$shape" ]; then HL_DEVICE_SHAPE="$shape" "$bin" "$cmd" "$@" --device "$d"
  else "$bin" "$cmd" "$@" --device "$d"; fi
}
# median of the numbers on stdin (empty when none)
median() { sort -g | awk '{a[NR] = $1} END {if (NR) print (NR % 2 ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2)}'; }

status=0
{
  echo "# Device report: $dev${other:+ against $other}"
  echo
  echo "$(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) host cores; \`tests/gpu.sh $*\`."
  echo
  echo '```'
  "$bin" devices 2>&1
  echo '```'
} >"$rep"

if has crosscheck; then
  say "crosscheck on $dev"
  spec_shape=""; [[ "$dev" == */* ]] && spec_shape="${dev##*/}"
  if HL_DEVICE_SHAPE="${spec_shape:-${HL_DEVICE_SHAPE:-}}" bash "$here/tests/crosscheck.sh" "${dev%%/*}" "$bin" >"$out/crosscheck.log" 2>&1; then
    verdict="agrees with the plain-C reference"
  else
    verdict="**DIFFERS** from the plain-C reference"; status=1
  fi
  { echo; echo "## Crosscheck"; echo
    echo "$dev $verdict: $(grep -c '^same:' "$out/crosscheck.log") files byte-identical, $(grep -c '^DIFFER' "$out/crosscheck.log") differing, \`check\` stages: $(grep -c '| ok |' "$out/crosscheck.log") ok, $(grep -c 'DIFFERS' "$out/crosscheck.log") differing (crosscheck.log)."
  } >>"$rep"
fi

if has suite; then
  say "the suite on $dev"
  d="${dev%%/*}"
  # left out: what needs a display, valgrind's CPU, a Slurm cluster, an
  # install prefix, Blender or assimp's own model files, none of them the device's
  skip='hl\.(viewer|valgrind|slurm|install|blender|fuzz|assimp_models)\.'
  spec_shape=""; [[ "$dev" == */* ]] && spec_shape="${dev##*/}"
  ( export HL_OPENCL_DEVICE="${d#cl:}"
    [ -n "$spec_shape" ] && export HL_DEVICE_SHAPE="$spec_shape"
    cd "$build" && ctest -E "$skip" -j"$(nproc)" --timeout 600 ) >"$out/suite.log" 2>&1
  rc=$?
  [ "$rc" -eq 0 ] || status=1
  { echo; echo "## The suite on $dev"; echo
    echo "$(grep -E 'tests passed' "$out/suite.log" || echo "ctest gave no summary (exit $rc)") (ctest -E '$skip'; suite.log)."
    grep -E '^\s+[0-9]+ - .*\((Failed|Timeout|SEGFAULT|Subprocess)' "$out/suite.log" | sed 's/^\s*/- failed: /'
    echo "$(grep -c '(Skipped)' "$out/suite.log") skipped (listed in suite.log)."
  } >>"$rep"
fi

# bench_mesh NAME MESH PRECOMPUTE_OPTS...: precompute once on DEVICE (its rays
# on the host's cores), then `bench` at M = 200 alternating the devices
bench_mesh() {
  local name="$1" mesh="$2"; shift 2
  local hlt="$work/$name.hlt"
  if [ ! -s "$hlt" ]; then
    say "precompute $name"
    local t0; t0=$(date +%s.%N)
    run "$dev" precompute "$mesh" "$@" -q -o "$hlt" >"$out/$name-precompute.log" 2>&1 || {
      echo "- $name: precompute failed (see $name-precompute.log)" >>"$rep"; return; }
    echo "- $name: precomputed in $(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN {printf "%.1f", b - a}') s on $dev ($*)" >>"$rep.pre"
  fi
  for r in $(seq 1 "$rounds"); do
    for spec in "$dev" ${other:+"$other"}; do
      say "bench $name on $spec, round $r"
      run "$spec" bench "$hlt" --env "$here/data/city.exr" --terms 200 --select transport --no-ref-timing --reps 15 \
          --vertices 64 --continuous 0 --no-banding -o "$work/bench-$name" >"$work/b.log" 2>&1
      cat "$work/b.log" >>"$out/bench-$name.log"
      line=$(grep -E 'lighting changes/s at M = 200' "$work/b.log" | tail -n 1)
      [ -n "$line" ] || { echo "| $name | $spec | failed: see bench-$name.log | | | | |" >>"$rep.rows"; continue; }
      # "N lighting changes/s ...; dot products X ms for Y MB = F (lo to hi) of the read bandwidth (B GB/s)"
      echo "$line" | sed -E 's/.*: ([0-9.]+) lighting changes\/s.*dot products ([0-9.]+) ms for ([0-9.]+) MB = ([0-9.]+) .*read bandwidth \(([0-9.]+) GB\/s\).*/\1 \2 \3 \4 \5/' |
        { read -r cps ms mb frac gbs; echo "| $name | $spec | $cps | $ms ms | $mb MB | $gbs GB/s | $frac |" >>"$rep.rows"
          echo "$name $spec $cps $ms $frac $gbs" >>"$work/figures"; }
    done
  done
}

if has bunny || has dragon; then
  : >"$rep.rows"; : >"$rep.pre"; : >"$work/figures"
  has bunny && bench_mesh bunny "$shared/meshes/bunny.obj" --ground
  has dragon && bench_mesh dragon "$shared/meshes/dragon_full.obj.gz" --ground
  { echo; echo "## Lighting changes at M = 200 (\`bench\`, city.exr, $rounds runs a device, alternating)"; echo
    cat "$rep.pre"; echo
    echo "| mesh | device | changes/s | dot products | bytes a change | read-bandwidth probe | fraction of the probe |"
    echo "|---|---|---|---|---|---|---|"
    cat "$rep.rows"; echo
    for name in bunny dragon; do
      for spec in "$dev" ${other:+"$other"}; do
        m=$(awk -v n="$name" -v s="$spec" '$1 == n && $2 == s {print $3}' "$work/figures" | median)
        [ -n "$m" ] && echo "- $name on $spec: median $m changes/s, dot products at $(awk -v n="$name" -v s="$spec" '$1 == n && $2 == s {print $5}' "$work/figures" | median) of a probe of $(awk -v n="$name" -v s="$spec" '$1 == n && $2 == s {print $6}' "$work/figures" | median) GB/s (medians)"
      done
      if [ -n "$other" ]; then
        a=$(awk -v n="$name" -v s="$dev" '$1 == n && $2 == s {print $3}' "$work/figures" | median)
        b=$(awk -v n="$name" -v s="$other" '$1 == n && $2 == s {print $3}' "$work/figures" | median)
        [ -n "$a" ] && [ -n "$b" ] && echo "- $name: $dev makes $(awk -v a="$a" -v b="$b" 'BEGIN {printf "%.2f", a / b}') times the changes/s of $other"
      fi
    done
  } >>"$rep"
  rm -f "$rep.rows" "$rep.pre"
fi

if has dynamic; then
  # the low-resolution bunny with its ground (K 32, M 16, R 256), then the
  # full bunny with its ground (its .hlt from the bunny step, or made here)
  [ -s "$work/lowres.hlt" ] || run "$dev" precompute "$here/data/bunny_lowres.obj" --ground -q -o "$work/lowres.hlt" >/dev/null 2>&1
  [ -s "$work/bunny.hlt" ] || run "$dev" precompute "$shared/meshes/bunny.obj" --ground -q -o "$work/bunny.hlt" >/dev/null 2>&1
  { echo; echo "## Dynamic frames (\`bench-dynamic\`, K 32, M 16, R 256; the traced rays on the host's cores)"; echo; } >>"$rep"
  for mesh in lowres bunny; do
    [ -s "$work/$mesh.hlt" ] || { echo "- $mesh: no transport to bench (precompute failed)" >>"$rep"; continue; }
    if [ "$mesh" = lowres ]; then envs=(--env "$here/data/city.exr" --env "$shared/envmaps/studio.exr" --sky); samples=1,4,16,64
    else envs=(--env "$here/data/city.exr"); samples=1,4; fi
    for spec in "$dev" ${other:+"$other"}; do
      say "bench-dynamic $mesh on $spec"
      run "$spec" bench-dynamic "$work/$mesh.hlt" "${envs[@]}" --settings 32:16 --terms 200 --samples "$samples" \
          --shadow-res 256 -o "$work/dyn-$mesh" >"$work/d.log" 2>&1
      cat "$work/d.log" >>"$out/bench-dynamic-$mesh.log"
      echo "- **$mesh on $spec**:" >>"$rep"
      grep -E '^bench-dynamic: [^:]+: (goal|moved)' "$work/d.log" | sed 's/^bench-dynamic: /  - /' >>"$rep"
      grep -q 'goal:' "$work/d.log" || echo "  - failed: see bench-dynamic-$mesh.log" >>"$rep"
    done
  done
fi

echo >>"$rep"
echo "The whole report took $(($(date +%s) - t_start)) s." >>"$rep"
cat "$rep"
exit "$status"
