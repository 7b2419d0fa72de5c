#!/usr/bin/env bash
# test_cli.sh CASE - end-to-end checks of the haarlight command.
# Env: HL_BIN (the binary), HL_TMP (scratch), HL_REPO_DATA (data/), HL_SRC
# (the source tree, for kernels).
set -u
bin="${HL_BIN:?}"
src="${HL_SRC:-$(cd "$(dirname "$0")/.." && pwd)}"
tmp="${HL_TMP:-/tmp}/cli.$$"
data="${HL_REPO_DATA:?}"
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

# expect_error NAME EXPECTED_RC MESSAGE_PART OUTPUT -- ARGS...: the command
# must exit with EXPECTED_RC, print MESSAGE_PART on stderr, leave no OUTPUT.
expect_error() {
  local name="$1" want="$2" part="$3" out="$4"; shift 5
  "$bin" "$@" >"$tmp/out.txt" 2>"$tmp/err.txt"
  local rc=$?
  local msg; msg="$(head -c 300 "$tmp/err.txt" | tr '\n' ' ')"
  echo "$name: exit $rc: $msg"
  [ "$rc" -eq "$want" ] || fail "$name: exit code $rc, expected $want"
  grep -q -- "$part" "$tmp/err.txt" || fail "$name: message lacks '$part'"
  [ -n "$out" ] && [ -e "$out" ] && fail "$name: $out was written"
  ls "$tmp" | grep -q '\.tmp\.' && fail "$name: a temporary file was left behind"
  [ -z "${partial_expected:-}" ] && ls "$tmp" | grep -q '\.partial$' && fail "$name: a partial file was left behind"
  return 0
}

small=(-C 16 -N 16 -q)

case "${1:-}" in
bad_input)
  printf 'v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n' >"$tmp/nan.obj"
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n' >"$tmp/index.obj"
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\n' >"$tmp/nofaces.obj"
  head -c 4096 /dev/urandom >"$tmp/noise.obj"
  printf 'hello, I am not a mesh\n' >"$tmp/text.ply"
  expect_error nan 1 "nan.obj" "$tmp/o1.hlt" -- precompute "$tmp/nan.obj" -o "$tmp/o1.hlt" "${small[@]}"
  expect_error index 1 "index.obj" "$tmp/o2.hlt" -- precompute "$tmp/index.obj" -o "$tmp/o2.hlt" "${small[@]}"
  expect_error nofaces 1 "nofaces.obj" "$tmp/o3.hlt" -- precompute "$tmp/nofaces.obj" -o "$tmp/o3.hlt" "${small[@]}"
  expect_error noise 1 "noise.obj" "$tmp/o4.hlt" -- precompute "$tmp/noise.obj" -o "$tmp/o4.hlt" "${small[@]}"
  expect_error text 1 "text.ply" "$tmp/o5.hlt" -- precompute "$tmp/text.ply" -o "$tmp/o5.hlt" "${small[@]}"
  expect_error missing 1 "missing.obj" "$tmp/o6.hlt" -- precompute "$tmp/missing.obj" -o "$tmp/o6.hlt" "${small[@]}"
  expect_error unwritable 1 "no/such/dir" "" -- precompute "$data/bunny_lowres.obj" -o "$tmp/no/such/dir/x.hlt" "${small[@]}"
  ;;
bad_options)
  m="$data/bunny_lowres.obj"
  expect_error N_not_pow2 2 "power of two" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" -N 48
  expect_error N_small 2 "power of two" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" -N 4
  expect_error C_zero 2 "cubemap" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" -C 0
  expect_error K_negative 2 "--terms" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --terms -3
  expect_error K_zero 2 "--terms" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --terms 0
  expect_error eps_one 2 "--energy" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --energy 1
  expect_error eps_text 2 "--energy" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --energy lots
  expect_error supersample 2 "--supersample" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --supersample 16
  expect_error quant 2 "--quant" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --quant fp4
  expect_error device 2 "--device" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --device gpu
  expect_error no_platform 1 "does not exist" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --device cl:9:0
  expect_error no_output 2 "no output" "" -- precompute "$m"
  expect_error unknown_opt 2 "unknown option" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --frobnicate
  expect_error all_and_energy 2 "contradict" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --terms all --energy 0.1
  expect_error unknown_cmd 2 "unknown command" "" -- relightify
  # interreflection: the counts, the ground's albedo, and a shard
  for v in 17 -1 two 1.5; do
    expect_error "bounces_$v" 2 "--bounces" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --bounces "$v"
  done
  expect_error bounce_rays_zero 2 "--bounce-rays" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --bounces 1 --bounce-rays 0
  expect_error bounce_rays_alone 2 "need --bounces" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --bounce-rays 16
  expect_error bounce_terms_zero 2 "--bounce-terms" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --bounces 1 --bounce-terms 0
  expect_error bounces_shard 2 "--direct-rows" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --bounces 1 --shard 0/2
  expect_error direct_rows_alone 2 "needs --bounces" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --direct-rows "$tmp/d.hlt"
  expect_error direct_rows_resume 2 "nothing to resume" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --bounces 1 --direct-rows "$tmp/d.hlt" --resume
  expect_error direct_rows_missing 1 "cannot open" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --bounces 1 --direct-rows "$tmp/none.hlt"
  for v in 1.2 -0.1 nan 0.5,0.5 0,0,0 0.5,0.5,0.5,0.5 red; do
    expect_error "ground_albedo_$v" 2 "--ground-albedo" "$tmp/x.hlt" -- precompute "$m" -o "$tmp/x.hlt" --ground-albedo "$v"
  done
  ;;
cl_equals_ref)
  # the OpenCL path and the plain-C reference write the same bytes
  m="$data/bunny_lowres.obj"
  for q in log8 linear8; do
    "$bin" precompute "$m" --ground --ground-res 16 -o "$tmp/cl.hlt" -C 32 -N 32 --quant $q -q || fail "cl run ($q)"
    "$bin" precompute "$m" --ground --ground-res 16 -o "$tmp/ref.hlt" -C 32 -N 32 --quant $q -q --device ref || fail "ref run ($q)"
    if cmp -s "$tmp/cl.hlt" "$tmp/ref.hlt"; then echo "$q: OpenCL and reference files identical ($(stat -c %s "$tmp/cl.hlt") bytes)"
    else fail "$q: OpenCL and reference files differ"; fi
  done
  # and the thread count and chunk size do not change the bytes
  "$bin" precompute "$m" --ground --ground-res 16 -o "$tmp/t1.hlt" -C 32 -N 32 -q --quant linear8 --threads 1 --chunk 77 || fail "1-thread run"
  cmp -s "$tmp/t1.hlt" "$tmp/cl.hlt" && echo "1 thread, chunk 77: identical" || fail "1 thread / chunk 77 differs"
  # a bounced transport: the same bytes both ways, said by precompute and info
  for dev in cl ref; do
    "$bin" precompute "$m" --ground --ground-res 16 -C 16 -N 16 --bounces 1 --bounce-rays 16 --device $dev \
      -o "$tmp/b_$dev.hlt" 2>"$tmp/b_$dev.txt" || fail "precompute --bounces 1 ($dev)"
  done
  grep "bounce" "$tmp/b_cl.txt"
  grep -q "bounce 1/1: .* vertices x 16 rays" "$tmp/b_cl.txt" || fail "precompute --bounces does not say the bounce"
  cmp -s "$tmp/b_cl.hlt" "$tmp/b_ref.hlt" && echo "bounced: OpenCL and reference files identical" || fail "bounced files differ"
  "$bin" info "$tmp/b_cl.hlt" | grep -q "direct and 1 bounce of diffuse interreflection" || fail "info does not say the bounce"
  "$bin" info "$tmp/cl.hlt" | grep -q "direct only" || fail "info does not say direct only"
  [ -e "$tmp/b_cl.hlt.direct.hlt" ] && fail "the direct rows' file was left behind"
  ;;
info)
  m="$data/bunny_lowres.obj"
  "$bin" precompute "$m" --ground --ground-res 8 -o "$tmp/i.hlt" -C 16 -N 16 -q --terms 20 || fail "precompute"
  "$bin" info "$tmp/i.hlt" >"$tmp/info.txt" || fail "info"
  cat "$tmp/info.txt"
  grep -q "rays culled" "$tmp/info.txt" || fail "info does not report culled rays"
  # fully occluded ground vertices have fewer than 20 non-zeros, so the
  # mean is below 20; no vertex may exceed it
  grep -q "max 20)" "$tmp/info.txt" || fail "--terms 20 must keep at most 20 per vertex, and 20 where available"
  head -c 1000 "$tmp/i.hlt" >"$tmp/trunc.hlt"
  expect_error truncated 1 "trunc.hlt" "" -- info "$tmp/trunc.hlt"
  ;;
interrupt)
  # SIGINT or SIGKILL part-way leaves no output, only SCENE.hlt.partial;
  # --resume continues it (with other chunks, threads or device) and writes
  # the same bytes as an unbroken run
  m="$data/bunny_lowres.obj"
  "$bin" precompute "$m" --ground -o "$tmp/whole.hlt" -q --chunk 64 || fail "unbroken run"
  "$bin" precompute "$m" --ground -o "$tmp/int.hlt" -q --device ref --chunk 64 &
  pid=$!
  sleep 1.5
  kill -INT $pid
  wait $pid
  rc=$?
  echo "interrupted run: exit $rc"
  [ "$rc" -eq 130 ] || fail "an interrupted run must exit 130"
  [ -e "$tmp/int.hlt" ] && fail "output written by an interrupted run"
  [ -s "$tmp/int.hlt.partial" ] || fail "no partial file kept for --resume"
  # other parameters: refused, and the partial file is kept
  partial_expected=1 expect_error resume_other_params 1 "other parameters" "$tmp/int.hlt" -- precompute "$m" --ground -N 32 --resume -o "$tmp/int.hlt"
  [ -s "$tmp/int.hlt.partial" ] || fail "a refused resume removed the partial file"
  "$bin" precompute "$m" --ground -o "$tmp/int.hlt" -q --device ref --threads 1 --chunk 100 --resume &
  pid=$!
  sleep 1.5
  kill -KILL $pid
  wait $pid
  echo "killed run: exit $?"
  [ -e "$tmp/int.hlt" ] && fail "output written by a killed run"
  "$bin" precompute "$m" --ground -o "$tmp/int.hlt" --chunk 300 --resume 2>"$tmp/resume.err" || fail "resume"
  grep -E "resuming|no .*partial" "$tmp/resume.err"
  # stderr is a file here, as in a batch job's log: whole progress lines,
  # the last at 100% with the rate and the time left, no carriage returns
  grep -E "^precompute: ([0-9]+)/\1 vertices \(100%\), [0-9.]+ Mrays/s, ETA 0 s$" "$tmp/resume.err" ||
    fail "no final progress line in a log that is not a terminal"
  grep -q $'\r' "$tmp/resume.err" && fail "carriage returns in a log that is not a terminal"
  cmp "$tmp/whole.hlt" "$tmp/int.hlt" || fail "a resumed run wrote other bytes than an unbroken one"
  echo "resumed after SIGINT and SIGKILL: same bytes as the unbroken run ($(stat -c %s "$tmp/int.hlt") bytes)"
  [ -e "$tmp/int.hlt.partial" ] && fail "partial file left after a complete run"
  ls "$tmp" | grep -q '\.tmp\.' && fail "temporary file left behind"
  ;;
opencl_faults)
  # each OpenCL fault names its cause and suggests the plain-C reference
  m="$data/bunny_lowres.obj"
  mkdir -p "$tmp/no_icds" "$tmp/k/kernels" "$tmp/k/host/src/core"
  OCL_ICD_VENDORS="$tmp/no_icds" expect_error no_platform 1 "no platform found.*--device ref" "$tmp/f1.hlt" -- precompute "$m" -o "$tmp/f1.hlt" "${small[@]}"
  cp -r "$src/kernels/." "$tmp/k/kernels/"
  cp "$src/host/src/core/hl_shared.h" "$tmp/k/host/src/core/"
  echo "kernel void broken( { }" >>"$tmp/k/kernels/maps/haar.cl"
  HL_KERNEL_DIR="$tmp/k/kernels" expect_error build_failure 1 "kernel build failed" "$tmp/f2.hlt" -- precompute "$m" -o "$tmp/f2.hlt" "${small[@]}"
  grep -q "build log" "$tmp/err.txt" || fail "build_failure: no build log"
  grep -q "error:" "$tmp/err.txt" || fail "build_failure: the log lacks the compiler's error"
  grep -q -- "--device ref" "$tmp/err.txt" || fail "build_failure: no suggestion of --device ref"
  # a job too big for the device memory granted is refused before any ray
  # is cast, whatever the machine's own memory; the same job in smaller
  # chunks fits the same limit and writes the same bytes as without it
  job=(precompute "$m" --ground --ground-res 16 -C 16 -N 32 -q)
  expect_error device_memory 1 "device memory limit of 16.0 MiB.*--device ref" "$tmp/f3.hlt" -- "${job[@]}" --chunk 2048 --device-memory 16M -o "$tmp/f3.hlt"
  HL_DEVICE_MEMORY=16M expect_error device_memory_env 1 "device memory limit of 16.0 MiB" "$tmp/f3.hlt" -- "${job[@]}" --chunk 2048 -o "$tmp/f3.hlt"
  "$bin" "${job[@]}" --chunk 256 --device-memory 16M -o "$tmp/capped.hlt" || fail "device_memory: the job in chunks of 256 did not fit 16 MiB"
  "$bin" "${job[@]}" --chunk 256 -o "$tmp/free.hlt" || fail "device_memory: the job without a limit failed"
  cmp -s "$tmp/capped.hlt" "$tmp/free.hlt" && echo "device_memory: chunks of 256 fit 16 MiB, same bytes as without the limit" ||
    fail "device_memory: the limit changed the output"
  expect_error device_memory_relight 1 "needs .* device memory limit of 1.0 MiB" "$tmp/f4.png" -- relight "$tmp/free.hlt" --sky --device-memory 1M -o "$tmp/f4.png" -q
  for bad in 0 -5 12Q 1.5G 99999999999G; do
    expect_error "device_memory_option_$bad" 2 "expected a byte count" "$tmp/f5.hlt" -- "${job[@]}" --device-memory "$bad" -o "$tmp/f5.hlt"
  done
  HL_DEVICE_MEMORY=lots expect_error device_memory_bad_env 1 "HL_DEVICE_MEMORY=lots" "$tmp/f5.hlt" -- "${job[@]}" -o "$tmp/f5.hlt"
  ;;
relight)
  # every output kind, from the sky and from a map, on both devices
  m="$data/bunny_lowres.obj"
  "$bin" precompute "$m" --ground --ground-res 12 -C 32 -N 32 -q -o "$tmp/r.hlt" || fail "precompute"
  for dev in cl ref; do
    "$bin" relight "$tmp/r.hlt" --sky -o "$tmp/r_$dev.ply" --device $dev -q || fail "relight ply ($dev)"
    head -c 600 "$tmp/r_$dev.ply" | grep -a -q "property float red" || fail "PLY without float colours ($dev)"
  done
  cmp -s "$tmp/r_cl.ply" "$tmp/r_ref.ply" && echo "relight: OpenCL and reference PLY identical" || fail "OpenCL and reference PLY differ"
  "$bin" relight "$tmp/r.hlt" --env "$data/city.exr" --rotate 30 --terms 50 --size 64x48 -o "$tmp/r.png" -q || fail "relight png"
  head -c 8 "$tmp/r.png" | od -An -c | grep -q "P   N   G" || fail "not a PNG"
  "$bin" relight "$tmp/r.hlt" --sky --size 64x48 -o "$tmp/r.exr" -q || fail "relight exr"
  "$bin" relight "$tmp/r.hlt" --sky --ply8 -o "$tmp/r8.ply" -q || fail "relight ply8"
  head -c 600 "$tmp/r8.ply" | grep -a -q "property uchar red" || fail "PLY8 without uchar colours"
  "$bin" check "$tmp/r.hlt" --env "$data/city.exr" --vertices 8 >"$tmp/check.txt" || fail "check found differences"
  grep -c "| ok |" "$tmp/check.txt" | grep -q 9 || fail "check did not report 9 stages ok"
  grep -q "(transport selection" "$tmp/check.txt" || fail "check did not use relight's default selection"
  # the other bases: their own stages checked, the stored rows equal
  for b in sh cube-haar; do
    "$bin" precompute "$m" -C 32 -N 32 --basis $b -q -o "$tmp/r_$b.hlt" || fail "precompute --basis $b"
    "$bin" check "$tmp/r_$b.hlt" --env "$data/city.exr" --vertices 8 >"$tmp/check_$b.txt" || fail "check --basis $b found differences"
    grep -q "DIFFERS" "$tmp/check_$b.txt" && fail "check of a $b file: $(grep DIFFERS "$tmp/check_$b.txt")"
    grep -q "rows stored in the file *|.*| ok |" "$tmp/check_$b.txt" || fail "check of a $b file: stored rows not checked"
  done
  grep -q "sh projection (float)" "$tmp/check_sh.txt" && grep -q "sh projection of the lighting" "$tmp/check_sh.txt" ||
    fail "check of an SH file did not check the projections"
  grep -q "cube face haar (float)" "$tmp/check_cube-haar.txt" && grep -q "cube faces + haar of the lighting" "$tmp/check_cube-haar.txt" ||
    fail "check of a cube-face file did not check its stages"
  echo "check: SH and cube-face files checked stage by stage"
  # each scheme's own weights on both sides: they keep different blocks
  for s in area unweighted; do
    "$bin" check "$tmp/r.hlt" --env "$data/city.exr" --vertices 2 --select $s >"$tmp/check_$s.txt" || fail "check --select $s found differences"
    grep -q "($s selection" "$tmp/check_$s.txt" || fail "check --select $s did not say so"
  done
  "$bin" check "$tmp/r.hlt" --select nope >/dev/null 2>&1 && fail "check --select nope accepted"
  # an output folder whose name holds a quote and a space
  out="$tmp/it's bench"
  "$bin" bench "$tmp/r.hlt" --sky --terms 10,all --select area --reps 2 --ref-reps 2 --vertices 16 --continuous 2 -o "$out" >/dev/null 2>&1 || fail "bench"
  for f in bench.md bench.csv bench.gp; do [ -s "$out/$f" ] || fail "bench wrote no $f"; done
  if command -v gnuplot >/dev/null; then [ -s "$out/bench.svg" ] || fail "bench drew no bench.svg"; fi
  [ -z "$(find "$out" -name '*.tmp.*')" ] || fail "bench left temporary files: $(ls "$out")"
  [ "$(wc -l <"$out/bench.csv")" -eq 3 ] || fail "bench.csv should hold a header and 2 rows"
  grep -q "and of 2 on the reference" "$out/bench.md" || fail "bench.md does not give the reference's repetitions"
  "$bin" bench "$tmp/r.hlt" --sky --ref-reps 0 -o "$out" >/dev/null 2>&1 && fail "bench --ref-reps 0 accepted"
  ;;
relight_bad)
  m="$data/bunny_lowres.obj"
  "$bin" precompute "$m" -C 16 -N 16 -q -o "$tmp/b.hlt" || fail "precompute"
  printf 'not an exr' >"$tmp/bad.exr"
  head -c 5000 "$data/city.exr" >"$tmp/trunc.exr"
  "$bin" relight "$tmp/b.hlt" --sky --size 10x10 -o "$tmp/square.exr" -q || fail "writing a 10x10 EXR"
  "$bin" relight "$tmp/b.hlt" --sky --size 10x7 -o "$tmp/odd.exr" -q || fail "writing a 10x7 EXR"
  # a transport file from another format version (the version follows the 8-byte magic)
  cp "$tmp/b.hlt" "$tmp/v2.hlt"
  printf '\x63' | dd of="$tmp/v2.hlt" bs=1 seek=8 conv=notrunc 2>/dev/null
  expect_error missing_env 1 "nosuch.exr" "$tmp/o.ply" -- relight "$tmp/b.hlt" --env "$tmp/nosuch.exr" -o "$tmp/o.ply"
  expect_error corrupt_env 1 "bad.exr" "$tmp/o.ply" -- relight "$tmp/b.hlt" --env "$tmp/bad.exr" -o "$tmp/o.ply"
  expect_error truncated_env 1 "trunc.exr" "$tmp/o.ply" -- relight "$tmp/b.hlt" --env "$tmp/trunc.exr" -o "$tmp/o.ply"
  # no layout is 10:7; a square map is an angular light probe, but not an
  # equirectangular map when --layout says so; --layout takes known names
  expect_error odd_shape_env 1 "odd.exr.*angular map.*cube cross" "$tmp/o.ply" -- relight "$tmp/b.hlt" --env "$tmp/odd.exr" -o "$tmp/o.ply"
  expect_error square_as_equirect 1 "square.exr.*not an equirectangular" "$tmp/o.ply" -- relight "$tmp/b.hlt" --env "$tmp/square.exr" --layout equirect -o "$tmp/o.ply"
  expect_error bad_layout 2 "--layout" "$tmp/o.ply" -- relight "$tmp/b.hlt" --env "$tmp/square.exr" --layout globe -o "$tmp/o.ply"
  "$bin" relight "$tmp/b.hlt" --env "$tmp/square.exr" -o "$tmp/o.ply" -q || fail "a square map (angular light probe) was refused"
  rm -f "$tmp/o.ply"
  expect_error terms_zero 2 "--terms" "$tmp/o.ply" -- relight "$tmp/b.hlt" --sky --terms 0 -o "$tmp/o.ply"
  expect_error other_version 1 "v2.hlt" "$tmp/o.ply" -- relight "$tmp/v2.hlt" --sky -o "$tmp/o.ply"
  expect_error bad_ext 2 "o.jpg" "$tmp/o.jpg" -- relight "$tmp/b.hlt" --sky -o "$tmp/o.jpg"
  expect_error env_and_sky 2 "contradict" "$tmp/o.ply" -- relight "$tmp/b.hlt" --env "$data/city.exr" --sun-size 3 -o "$tmp/o.ply"
  expect_error unwritable 1 "no/dir" "" -- relight "$tmp/b.hlt" --sky -o "$tmp/no/dir/o.png"
  ;;
relight_surroundings)
  # lit by the example surroundings (a lamp orbiting the bunny): loads and
  # says what it holds, two times give different colours, bad options exit 2
  m="$data/bunny_lowres.obj"
  sur="$data/surroundings/lamp_orbit.gltf"
  "$bin" precompute "$m" --ground --ground-res 12 -C 16 -N 16 -q -o "$tmp/s.hlt" || fail "precompute"
  "$bin" relight "$tmp/s.hlt" --surroundings "$sur" -o "$tmp/s0.ply" 2>"$tmp/s0.txt" || fail "relight --surroundings"
  cat "$tmp/s0.txt"
  grep -q "44 triangles, 1 of 3 bodies emitting; animation 0 to 4 s, posed at 0 s" "$tmp/s0.txt" || fail "no line saying what the surroundings hold"
  grep -q "open directions black" "$tmp/s0.txt" || fail "without --env or --sky the open directions are not said to be black"
  "$bin" relight "$tmp/s.hlt" --surroundings "$sur" --time 2 -o "$tmp/s2.ply" -q || fail "relight --time 2"
  "$bin" relight "$tmp/s.hlt" --surroundings "$sur" --time 9 --sky -o "$tmp/s9.ply" 2>"$tmp/s9.txt" || fail "relight --time 9 --sky"
  grep -q "posed at 4 s (held at the last key)" "$tmp/s9.txt" || fail "--time past the end not said to be held"
  [ -s "$tmp/s0.ply" ] && [ -s "$tmp/s2.ply" ] || fail "no PLY written"
  cmp -s "$tmp/s0.ply" "$tmp/s2.ply" && fail "the lamp at 0 s and at 2 s gave identical colours"
  expect_error time_negative 2 "--time" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$sur" --time -1 -o "$tmp/o.ply"
  expect_error time_nan 2 "--time" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$sur" --time nan -o "$tmp/o.ply"
  expect_error time_text 2 "--time" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$sur" --time soon -o "$tmp/o.ply"
  expect_error time_alone 2 "--time needs --surroundings" "$tmp/o.ply" -- relight "$tmp/s.hlt" --time 1 -o "$tmp/o.ply"
  # the references are of direct light: a bounced file is refused, not measured against them
  "$bin" precompute "$data/bunny_lowres.obj" -N 16 -C 16 --bounces 1 --bounce-rays 4 -q -o "$tmp/b.hlt" || fail "bounced precompute"
  expect_error reference_bounced 2 "bounces" "$tmp/o.ply" -- relight "$tmp/b.hlt" --surroundings "$sur" --reference exact -o "$tmp/o.ply"
  expect_error surroundings_missing 1 "nosuch.gltf" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$tmp/nosuch.gltf" -o "$tmp/o.ply"
  # what the capture costs is said; the file's placement moves the lamp
  grep -q "capture: 44 triangles, .* MiB on the host and .* MiB on the device, .* ms a capture" "$tmp/s0.txt" || fail "no line saying what the capture costs"
  "$bin" relight "$tmp/s.hlt" --surroundings "$sur" --surroundings-transform 0,0,0,1,180 -o "$tmp/sy.ply" -q || fail "relight --surroundings-transform"
  cmp -s "$tmp/s0.ply" "$tmp/sy.ply" && fail "the lamp turned half about +Y gave identical colours"
  "$bin" relight "$tmp/s.hlt" --surroundings "$sur" --surroundings-transform 0,0,0,1,0 -o "$tmp/sI.ply" -q || fail "identity placement"
  cmp -s "$tmp/s0.ply" "$tmp/sI.ply" || fail "the identity placement changed the colours"
  for v in 1,2,3 1,2,3,0,0 1,2,3,-2,0 1,nan,3,1,0 1,2,3,inf,0 1,2,3,1,0,7 a,b,c,d,e; do
    expect_error "transform_$v" 2 "--surroundings-transform" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$sur" --surroundings-transform "$v" -o "$tmp/o.ply"
  done
  expect_error transform_scale_zero 2 "SCALE 0 must be" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$sur" --surroundings-transform 0,0,0,0,0 -o "$tmp/o.ply"
  printf 'v 1e38 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n' >"$tmp/far.obj"
  expect_error surroundings_far 1 "far.obj: capture: triangle 0" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$tmp/far.obj" -o "$tmp/o.ply"
  expect_error transform_alone 2 "--surroundings-transform needs --surroundings" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings-transform 0,0,0,1,0 -o "$tmp/o.ply"
  # more capture points: the lamp orbits close, so the one point's bound is
  # said with the way to follow it, and 8 points are placed and said
  grep -q "capture points: 1 of 1; parallax up to" "$tmp/s0.txt" || fail "no line saying the capture point's parallax bound"
  grep -q -- "--probes 32 follows it" "$tmp/s0.txt" || fail "a near lamp's parallax does not point at --probes"
  "$bin" relight "$tmp/s.hlt" --surroundings "$sur" --probes 8 -o "$tmp/sp.ply" 2>"$tmp/sp.txt" || fail "relight --probes 8"
  grep "capture points" "$tmp/sp.txt"
  grep -q "capture points: 8 of 8" "$tmp/sp.txt" || fail "--probes 8: not 8 points placed"
  cmp -s "$tmp/s0.ply" "$tmp/sp.ply" && fail "8 capture points gave the one point's colours"
  for v in 0 257 -1 2.5 many; do
    expect_error "probes_$v" 2 "--probes" "$tmp/o.ply" -- relight "$tmp/s.hlt" --surroundings "$sur" --probes "$v" -o "$tmp/o.ply"
  done
  expect_error probes_alone 2 "--probes needs --surroundings" "$tmp/o.ply" -- relight "$tmp/s.hlt" --probes 8 -o "$tmp/o.ply"
  ;;
*) echo "usage: $0 bad_input|bad_options|cl_equals_ref|info|interrupt|opencl_faults|relight|relight_bad|relight_surroundings"; exit 2 ;;
esac
echo "$((fails == 0 ? 1 : 0)) passed, $fails failed" >/dev/null
[ "$fails" -eq 0 ] && echo "${1}: passed" || echo "${1}: FAILED ($fails)"
[ "$fails" -eq 0 ]
