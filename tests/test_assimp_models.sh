#!/usr/bin/env bash
# test_assimp_models.sh - every model of Debian's assimp-testmodels package
# through `haarlight precompute`: each must load (exit 0, an output file)
# or be refused (exit 1, a message on stderr that names the file, no output
# file); a signal, a timeout, a sanitizer report, another exit code or an
# empty message is a failure.
#
# Env: HL_BIN (the binary), HL_TMP (scratch), HL_ASSIMP_MODELS (default
# /usr/share/assimp/models; absent: exit 77, skipped), HL_SANITIZE (1: the
# binary is built with ASan + UBSan; unset: told from the binary),
# HL_MODEL_MEM_MB (memory limit per file, default 4096), HL_MODEL_TIME_S
# (time limit per file, default 120), HL_MODEL_JOBS (files at a time,
# default 2).
#
# The plain-C reference (--device ref) runs the precompute: the mesh goes
# through the same loader whatever the device, and it spares each file
# the OpenCL platform's start-up (PoCL compiles or loads its kernels per
# process), which would dominate a run of a few hundred tiny precomputes.
set -u
bin="${HL_BIN:?}"
models="${HL_ASSIMP_MODELS:-/usr/share/assimp/models}"
mem_mb="${HL_MODEL_MEM_MB:-4096}"
time_s="${HL_MODEL_TIME_S:-120}"
jobs_max="${HL_MODEL_JOBS:-2}"
here="$(cd "$(dirname "$0")" && pwd)"

if [ ! -d "$models" ]; then
  echo "SKIP: $models not found (Debian package assimp-testmodels; or set HL_ASSIMP_MODELS)"
  exit 77
fi
if [ ! -x "$bin" ]; then
  echo "FAIL: $bin is not an executable"
  exit 1
fi

tmp="$(mktemp -d "${HL_TMP:-/tmp}/assimp_models.XXXXXX")" || exit 1
trap 'rm -rf "$tmp"' EXIT

# The extensions assimp 5.2.5 (Debian 12's libassimp5) gives to an
# importer, as aiGetImportFormatCount() / aiGetImportFormatDescription(i)
# ->mFileExtensions list them (M3D is not built in Debian's package).
# Textures, .bin buffers, .mtl, .txt and the like are not models.
exts=" x obj amf 3ds prj md3 md2 ply mdl ase ask hmp smd vta mdc md5mesh md5camera md5anim stl lwo lxo dxf
 enff nff raw sib off ac acc ac3d bvh xml irrmesh irr q3o q3s b3d dae zae ter csm 3d uc lws mot mesh ogex ms3d
 cob scn blend bsp pk3 ndo ifc ifczip step stp xgl zgl fbx assbin gltf glb 3mf x3d x3db pmx iqm "
exts="$(printf '%s' "$exts" | tr '\n' ' ')"

# Sanitizer build: `ulimit -v` cannot hold ASan's shadow reservations, so
# ASan's hard RSS limit stands in for it. There, going past the limit is a
# failure: ASan reports an allocation it cannot make through operator new
# instead of throwing std::bad_alloc, so assimp never sees it fail. A
# sanitizer's report exits with its own code (86; LeakSanitizer 23), and
# LeakSanitizer skips assimp's own leaks on malformed files (see
# tests/fuzz/lsan-mesh.supp).
sanitize="${HL_SANITIZE:-}"
if [ -z "$sanitize" ]; then
  if grep -q -a -m1 '__asan_init' "$bin" 2>/dev/null; then sanitize=1; else sanitize=0; fi
fi
case "$sanitize" in ON|on|1|TRUE|true) sanitize=1 ;; *) sanitize=0 ;; esac
if [ "$sanitize" = 1 ]; then
  export ASAN_OPTIONS="hard_rss_limit_mb=$mem_mb:exitcode=86${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
  export UBSAN_OPTIONS="print_stacktrace=1:exitcode=86${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
  supp="$here/fuzz/lsan-mesh.supp"
  [ -f "$supp" ] && export LSAN_OPTIONS="suppressions=$supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
fi
have_time=0
[ -x /usr/bin/time ] && have_time=1

# run_one INDEX FILE: runs the precompute; writes one line to
# $tmp/res/INDEX: STATUS<TAB>SECONDS<TAB>PEAK_KB<TAB>FILE<TAB>DETAIL.
run_one() {
  local i="$1" f="$2"
  local out="$tmp/out_$i.hlt" err="$tmp/err_$i.txt" stats="$tmp/stats_$i.txt"
  local t0 t1 rc
  t0=$(date +%s%N)
  (
    [ "$sanitize" = 1 ] || ulimit -v $((mem_mb * 1024))
    cmd=(timeout -k 5 "$time_s" "$bin" precompute "$f" -o "$out" -C 8 -N 8 --device ref --threads 1 -q)
    if [ "$have_time" = 1 ]; then
      exec /usr/bin/time -f '%M' -o "$stats" "${cmd[@]}"
    else
      exec "${cmd[@]}"
    fi
  ) >/dev/null 2>"$err"
  rc=$?
  t1=$(date +%s%N)
  local secs peak msg status detail
  secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", (b - a) / 1e9 }')
  peak=$( [ -s "$stats" ] && tail -n 1 "$stats" || echo "?")
  case "$peak" in *[!0-9]*|'') peak="?" ;; esac
  # /usr/bin/time adds its own lines to stderr after a signal; drop them
  msg="$(grep -v '^Command \(exited with non-zero status\|terminated by signal\)' "$err" | head -c 400 | tr '\n\t' '  ')"
  if grep -q -E 'AddressSanitizer|LeakSanitizer|UndefinedBehaviorSanitizer|runtime error:' "$err"; then
    status=FAIL
    detail="sanitizer: $(grep -m1 -E 'Sanitizer|runtime error:' "$err" | head -c 300)"
  elif [ "$rc" -eq 124 ] || { [ "$rc" -eq 137 ] && [ "$(awk -v s="$secs" -v l="$time_s" 'BEGIN { print (s >= l) }')" = 1 ]; }; then
    status=FAIL
    detail="timeout after ${time_s} s"
  elif [ "$rc" -gt 128 ]; then
    status=FAIL
    detail="killed by signal $(kill -l $((rc - 128)) 2>/dev/null || echo $((rc - 128))): $msg"
  elif [ "$rc" -eq 0 ]; then
    if [ -s "$out" ]; then status=LOADED detail=""
    else status=FAIL detail="exit 0 but no output file"; fi
  elif [ "$rc" -eq 1 ]; then
    if [ -z "${msg// /}" ]; then status=FAIL detail="exit 1 with an empty message"
    elif [ -e "$out" ] || [ -e "$out.partial" ]; then status=FAIL detail="refused but left an output file: $msg"
    elif ! grep -q -F -- "$f" "$err"; then status=FAIL detail="message does not name the file: $msg"
    else status=REFUSED detail="$msg"; fi
  else
    status=FAIL
    detail="exit $rc: $msg"
  fi
  printf '%s\t%s\t%s\t%s\t%s\n' "$status" "$secs" "$peak" "$f" "$detail" >"$tmp/res/$i"
  rm -f "$out" "$out.partial" "$err" "$stats"
}

mkdir -p "$tmp/res"
files=()
while IFS= read -r -d '' f; do
  name="${f##*/}"
  case "$name" in *.*) ;; *) continue ;; esac
  ext="$(printf '%s' "${name##*.}" | tr '[:upper:]' '[:lower:]')"
  case "$exts" in *" $ext "*) files+=("$f") ;; esac
done < <(find "$models" -type f -print0 | sort -z)
if [ "${#files[@]}" -eq 0 ]; then
  echo "FAIL: no model files under $models"
  exit 1
fi
echo "assimp test models: ${#files[@]} files under $models (limits: ${mem_mb} MB, ${time_s} s per file, $jobs_max at a time, sanitizer build: $sanitize)"

start=$(date +%s)
i=0
for f in "${files[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n; done
  run_one "$i" "$f" &
  i=$((i + 1))
done
wait

loaded=0 refused=0 failed=0
missing=0
for ((k = 0; k < ${#files[@]}; k++)); do
  if [ ! -s "$tmp/res/$k" ]; then
    echo "FAIL: ${files[$k]}: no result recorded"
    missing=$((missing + 1))
    continue
  fi
  IFS=$'\t' read -r status secs peak f detail <"$tmp/res/$k"
  case "$status" in
    LOADED) loaded=$((loaded + 1)) ;;
    REFUSED) refused=$((refused + 1)); echo "refused: $f: $detail" ;;
    *) failed=$((failed + 1)) ;;
  esac
done
echo
echo "slowest files (seconds, peak KB):"
cat "$tmp"/res/* | sort -t $'\t' -k2,2 -g -r | head -n 8 | awk -F '\t' '{ printf "  %6s s %9s KB  %s  %s\n", $2, $3, $1, $4 }'
echo "largest peak memory (KB):"
cat "$tmp"/res/* | awk -F '\t' '$3 != "?"' | sort -t $'\t' -k3,3 -g -r | head -n 5 | awk -F '\t' '{ printf "  %9s KB %6s s  %s  %s\n", $3, $2, $1, $4 }'
echo
failed=$((failed + missing))
echo "loaded $loaded, refused $refused, failed $failed of ${#files[@]} files in $(( $(date +%s) - start )) s"
if [ "$failed" -ne 0 ]; then
  echo "failures:"
  cat "$tmp"/res/* | awk -F '\t' '$1 == "FAIL" { printf "  FAIL: %s: %s\n", $4, $5 }'
  exit 1
fi
exit 0
