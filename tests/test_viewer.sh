#!/usr/bin/env bash
# test_viewer.sh CASE - the viewer in a real window under Xvfb.
#   capture_sky  default camera, built-in sky: capture against relight
#   capture_env  data/city.exr turned by 90 degrees, explicit camera
#   drop         an unreadable dropped file keeps the lighting; a good one
#                switches to it (--drop takes the drop callback's path)
#   bad_input    errors that come before any window (no X needed)
# Env: HL_BIN, HL_COMPARE (test_viewer), HL_TMP, HL_REPO_DATA,
# HL_VIEWER_BUILT (ON/OFF). Exit 77 = skipped.
set -u
bin="${HL_BIN:?}"
compare="${HL_COMPARE:?}"
data="${HL_REPO_DATA:?}"
mkdir -p "${HL_TMP:-/tmp}"
tmp="$(mktemp -d "${HL_TMP:-/tmp}/viewer.XXXXXX")" || exit 1
trap 'rm -rf "$tmp"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
skip() { echo "SKIPPED: $*"; exit 77; }

# A small scene (about 2k vertices) so that each case takes a second or two.
scene() {
  "$bin" precompute "$data/bunny_lowres.obj" --ground --ground-res 16 -C 16 -N 16 -q -o "$tmp/s.hlt" ||
    { echo "FAIL: precompute"; exit 1; }
}

# view ARGS...: the viewer under a private Xvfb (24-bit screen), output in
# $tmp/view.txt; skips when no X server or no OpenGL 3.3 context can be had.
view() {
  command -v xvfb-run >/dev/null || skip "xvfb-run is not installed (Debian: xvfb, xauth)"
  xvfb-run -a -s "-screen 0 1280x1024x24" "$bin" view "$@" >"$tmp/view.txt" 2>&1
  local rc=$?
  cat "$tmp/view.txt"
  if grep -q "Xvfb failed to start\|cannot open a window\|cannot create a window" "$tmp/view.txt"; then
    skip "no X server with OpenGL 3.3 could be started under xvfb-run"
  fi
  return $rc
}

# same_picture NAME VIEW.exr RELIGHT.exr EV
same_picture() {
  echo "$1:"
  "$compare" compare "$2" "$3" "$4" || fail "$1: the viewer's capture differs from relight's picture"
  grep -q "display check: 0 of\|largest difference [01] codes" "$tmp/view.txt" ||
    fail "$1: the window's tone-mapped pixels differ from hl_tonemap_srgb8 by more than 1 code"
}

case "${1:-}" in
capture_sky|capture_env|drop)
  [ "${HL_VIEWER_BUILT:-OFF}" = ON ] || skip "haarlight was built without the viewer (HL_WITH_VIEWER=OFF or no GLFW/OpenGL)"
  ;;
esac

case "${1:-}" in
capture_sky)
  scene
  cam=(--size 320x240 --exposure 0.5)
  "$bin" relight "$tmp/s.hlt" --sky "${cam[@]}" -q -o "$tmp/relight.exr" || fail "relight"
  view "$tmp/s.hlt" "${cam[@]}" --no-glare --frames 3 --screenshot "$tmp/view.exr" || fail "view exited with an error"
  same_picture "built-in sky, automatic framing" "$tmp/view.exr" "$tmp/relight.exr" 0.5
  ;;
capture_env)
  scene
  # low and wide, so that most of the picture is the map: a turn of 1 degree fails
  cam=(--size 256x192 --exposure -1 --rotate 90 --terms 50 --fov 70 --eye 14,4,16 --target 0,6,0)
  "$bin" relight "$tmp/s.hlt" --env "$data/city.exr" "${cam[@]}" -q -o "$tmp/relight.exr" || fail "relight"
  view "$tmp/s.hlt" --env "$data/city.exr" "${cam[@]}" --no-glare --frames 2 --screenshot "$tmp/view.exr" ||
    fail "view exited with an error"
  same_picture "city.exr turned 90 degrees, M = 50, explicit camera" "$tmp/view.exr" "$tmp/relight.exr" -1
  # the glare adds light and the PNG goes through the project's writer
  view "$tmp/s.hlt" --env "$data/city.exr" "${cam[@]}" --frames 2 --screenshot "$tmp/glare.png" || fail "view with glare"
  [ "$(head -c 8 "$tmp/glare.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] ||
    fail "the PNG screenshot has no PNG signature"
  ;;
drop)
  scene
  cam=(--size 256x192 --exposure 0.5)
  head -c 3000 /dev/urandom >"$tmp/noise.exr"
  "$bin" relight "$tmp/s.hlt" --sky "${cam[@]}" -q -o "$tmp/sky.exr" || fail "relight under the sky"
  "$bin" relight "$tmp/s.hlt" --env "$data/city.exr" "${cam[@]}" -q -o "$tmp/city.exr" || fail "relight under city.exr"
  view "$tmp/s.hlt" "${cam[@]}" --no-glare --drop "$tmp/noise.exr" --frames 2 --screenshot "$tmp/view1.exr"
  rc=$?
  [ $rc -eq 0 ] || fail "an unreadable dropped file stopped the viewer (exit $rc)"
  grep -q "noise.exr.*keeping the current lighting" "$tmp/view.txt" || fail "no error naming noise.exr"
  same_picture "after an unreadable drop (the sky kept)" "$tmp/view1.exr" "$tmp/sky.exr" 0.5
  view "$tmp/s.hlt" "${cam[@]}" --no-glare --drop "$tmp/noise.exr" --drop "$data/city.exr" --frames 2 \
    --screenshot "$tmp/view2.exr" || fail "view with a good drop"
  same_picture "after dropping city.exr" "$tmp/view2.exr" "$tmp/city.exr" 0.5
  ;;
bad_input)
  # expect NAME RC MESSAGE ARGS...: exit code and a message part on stderr
  expect() {
    local name="$1" want="$2" part="$3"; shift 3
    "$bin" view "$@" >"$tmp/out.txt" 2>"$tmp/err.txt"
    local rc=$?
    echo "$name: exit $rc: $(head -c 240 "$tmp/err.txt" | head -1)"
    [ "$rc" -eq "$want" ] || fail "$name: exit code $rc, expected $want"
    grep -q -- "$part" "$tmp/err.txt" || fail "$name: message lacks '$part'"
  }
  if [ "${HL_VIEWER_BUILT:-OFF}" != ON ]; then
    expect no_viewer 1 "built without the viewer" "$tmp/s.hlt"
  else
    scene
    printf 'not an image\n' >"$tmp/text.exr"
    expect missing_scene 1 "missing.hlt" "$tmp/missing.hlt"
    expect missing_env 1 "nothere.exr" "$tmp/s.hlt" --env "$tmp/nothere.exr"
    expect bad_env 1 "text.exr" "$tmp/s.hlt" --env "$tmp/text.exr"
    expect frames_zero 2 "--frames" "$tmp/s.hlt" --frames 0
    expect size_zero 2 "--size" "$tmp/s.hlt" --size 0x240
    expect size_text 2 "--size" "$tmp/s.hlt" --size big
    expect shot_ext 2 "--screenshot" "$tmp/s.hlt" --screenshot "$tmp/x.jpg"
    expect eye_is_target 1 "same point" "$tmp/s.hlt" --eye 1,1,1 --target 1,1,1
    expect unknown 2 "unknown option" "$tmp/s.hlt" --frobnicate
    expect no_scene 2 "no SCENE.hlt" --frames 1
  fi
  ;;
*) echo "usage: $0 capture_sky|capture_env|drop|bad_input"; exit 2 ;;
esac
[ "$fails" -eq 0 ] && echo "passed" || { echo "$fails failure(s)"; exit 1; }
