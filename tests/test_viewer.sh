#!/usr/bin/env bash
# test_viewer.sh CASE - the viewer in a real window under Xvfb.
#   capture_sky  default camera, built-in sky: capture against relight
#   capture_env  data/city.exr turned by 90 degrees, explicit camera
#   drop         an unreadable dropped file keeps the lighting; a good one
#                switches to it (--drop takes the drop callback's path)
#   bad_input    errors that come before any window (no X needed)
#   dynamic_rest   --dynamic with a transport, nothing moved: PRT's picture
#                  (as relight's), from SCENE.hlt and from MESH --hlt
#   dynamic_moved  --move: the dynamic method's picture (as relight-dynamic's
#                  with the same --move), and the HUD says so; the key b
#                  then brings PRT's picture back
#   dynamic_drag   --drag through the mouse's handlers: the translation it
#                  prints, given to relight-dynamic, gives the same picture
#   dynamic_anim   an animated glTF (tests/viewer/viewer_scene.c): --time as
#                  relight-dynamic's, and --play makes a new frame each frame
#   dynamic_bad    --dynamic's errors before any window (no X needed)
#   surroundings_capture  --surroundings data/surroundings/lamp_orbit.gltf
#                  --time 0.5, alone and over the sky: the object as relight's
#                  picture (the surroundings hidden with the key s, since
#                  relight does not draw them), and drawn they change it; at
#                  1.5 s from above, where none is in view, the first frame
#                  as relight's, and not as relight's at 0.5 s
#   surroundings_drag  --drag on the lamp moves it (horizontally) and its
#                  light: the object no longer looks as relight's; b puts it
#                  back (relight's picture again); a press on the object in
#                  front of the surroundings grabs nothing
#   surroundings_unchanged  b with nothing moved: the relighter finds nothing
#                  changed (HUD "lighting: unchanged"); --play, or space,
#                  captures every frame; space again pauses (unchanged again)
#   surroundings_bad  --surroundings' and --time's errors (no X needed)
#   textured       tests/data/textured_box.gltf with --textures: the viewer's
#                  capture as relight --textures's picture, which differs from
#                  the picture without textures
# Env: HL_BIN, HL_COMPARE (test_viewer), HL_SCENE_GEN (viewer_scene), HL_TMP, HL_REPO_DATA,
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

# The same bunny with the default ground (96 quads), which relight-dynamic
# --ground makes too, so that PRT's, the viewer's and relight-dynamic's
# meshes are one, vertex for vertex.
dyn_scene() {
  "$bin" precompute "$data/bunny_lowres.obj" --ground -C 16 -N 16 -q -o "$tmp/d.hlt" ||
    { echo "FAIL: precompute"; exit 1; }
}
# Few lights, small maps, low order: a frame in about 0.1 s here. An explicit
# camera: the automatic framing would follow a moved body in relight-dynamic.
dyn=(--sky --lights 4 --shadow-res 64 --order 4)
dcam=(--size 256x192 --exposure 0.5 --eye 16,10,24 --target 1,3,0)
# The lamp and three dark occluders around the bunny (data/surroundings),
# posed at 0.5 s; the automatic framing, which shows the lamp and the wall.
sur=(--surroundings "$data/surroundings/lamp_orbit.gltf" --time 0.5)
scam=(--size 320x240 --exposure 0.5)

# hud_says NAME PATTERN: the last HUD line (the window title) printed at exit
hud_says() {
  grep "last HUD:" "$tmp/view.txt" | grep -q -- "$2" || fail "$1: the HUD does not say '$2'"
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

# must_differ A.exr B.exr EV WHY: compare's exit 1 (they differ) passes;
# 0 (the same picture) fails with WHY; anything else (unreadable) fails.
must_differ() {
  "$compare" compare "$1" "$2" "$3" >"$tmp/cmp.txt" 2>&1
  local rc=$?
  # the differences measured, against the tolerances of a match (FAIL here: they differ, as wanted)
  sed 's/^/  (must differ) /' "$tmp/cmp.txt"
  case $rc in
    1) ;;
    0) fail "$4" ;;
    *) cat "$tmp/cmp.txt"; fail "cannot compare $1 with $2" ;;
  esac
}

# same_picture NAME VIEW.exr RELIGHT.exr EV
same_picture() {
  echo "$1:"
  "$compare" compare "$2" "$3" "$4" || fail "$1: the viewer's capture differs from relight's picture"
  grep -q "display check: 0 of\|largest difference [01] codes" "$tmp/view.txt" ||
    fail "$1: the window's tone-mapped pixels differ from hl_tonemap_srgb8 by more than 1 code"
}

case "${1:-}" in
capture_sky|capture_bounced|capture_env|drop|dynamic_rest|dynamic_moved|dynamic_moments|dynamic_drag|dynamic_anim|\
surroundings_capture|surroundings_drag|surroundings_unchanged|textured)
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
capture_bounced)
  # a row a channel (coloured bounces off a red ground): the viewer's
  # device buffer gathers each channel's plane as relight does
  "$bin" precompute "$data/bunny_lowres.obj" --ground --ground-res 24 --ground-albedo 0.8,0.15,0.1 -N 16 -C 16 \
    --bounces 1 --bounce-rays 16 -q -o "$tmp/b.hlt" || fail "precompute --bounces"
  "$bin" info "$tmp/b.hlt" | grep -q "a row a colour channel" || fail "the file has no row a channel"
  cam=(--size 320x240 --exposure 0.5)
  "$bin" relight "$tmp/b.hlt" --sky "${cam[@]}" -q -o "$tmp/relight.exr" || fail "relight"
  view "$tmp/b.hlt" "${cam[@]}" --no-glare --frames 3 --screenshot "$tmp/view.exr" || fail "view exited with an error"
  same_picture "coloured bounces, built-in sky" "$tmp/view.exr" "$tmp/relight.exr" 0.5
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
dynamic_rest)
  dyn_scene
  "$bin" relight "$tmp/d.hlt" "${dcam[@]}" --sky -q -o "$tmp/prt.exr" || fail "relight"
  view --dynamic "$tmp/d.hlt" "${dyn[@]}" "${dcam[@]}" --no-glare --frames 2 --screenshot "$tmp/view.exr" ||
    fail "view --dynamic exited with an error"
  same_picture "--dynamic SCENE.hlt at rest" "$tmp/view.exr" "$tmp/prt.exr" 0.5
  hud_says "--dynamic SCENE.hlt at rest" "PRT at rest"
  view --dynamic "$data/bunny_lowres.obj" --ground --hlt "$tmp/d.hlt" "${dyn[@]}" "${dcam[@]}" --no-glare --frames 2 \
    --screenshot "$tmp/view2.exr" || fail "view --dynamic MESH --hlt exited with an error"
  same_picture "--dynamic MESH --ground --hlt SCENE.hlt at rest" "$tmp/view2.exr" "$tmp/prt.exr" 0.5
  hud_says "--dynamic MESH --hlt at rest" "PRT at rest"
  ;;
dynamic_moved)
  dyn_scene
  mv=(--move object:3,0,2)
  "$bin" relight-dynamic "$data/bunny_lowres.obj" --ground "${dyn[@]}" "${dcam[@]}" "${mv[@]}" -q -o "$tmp/rd.exr" ||
    fail "relight-dynamic"
  "$bin" relight "$tmp/d.hlt" "${dcam[@]}" --sky -q -o "$tmp/prt.exr" || fail "relight"
  view --dynamic "$tmp/d.hlt" "${dyn[@]}" "${dcam[@]}" "${mv[@]}" --no-glare --frames 2 --screenshot "$tmp/view.exr" ||
    fail "view --dynamic --move exited with an error"
  same_picture "--dynamic SCENE.hlt, object moved by 3,0,2" "$tmp/view.exr" "$tmp/rd.exr" 0.5
  hud_says "--dynamic SCENE.hlt, object moved" "dynamic K 4: irradiance .* + shadow maps .* + CSM build .* + CSM eval .* + shading .* = .* ms, [0-9]* shadow maps kept, 1 body moved"
  echo "the moved picture must not be the picture at rest:"
  must_differ "$tmp/view.exr" "$tmp/prt.exr" 0.5 "the moved frame looks like the frame at rest: the move did not show"
  view --dynamic "$data/bunny_lowres.obj" --ground "${dyn[@]}" "${dcam[@]}" "${mv[@]}" --no-glare --frames 2 \
    --screenshot "$tmp/view2.exr" || fail "view --dynamic MESH --ground --move exited with an error"
  same_picture "--dynamic MESH --ground, object moved by 3,0,2" "$tmp/view2.exr" "$tmp/rd.exr" 0.5
  hud_says "--dynamic MESH, object moved" "dynamic K 4"
  # b after a moved frame: bodies back at rest, so PRT's picture again
  view --dynamic "$tmp/d.hlt" "${dyn[@]}" "${dcam[@]}" "${mv[@]}" --keys b --no-glare --frames 2 \
    --screenshot "$tmp/view3.exr" || fail "view --dynamic --move --keys b exited with an error"
  grep -q "^  1 frames with a lighting change" "$tmp/view.txt" || fail "b: the frame back at rest was not relit"
  same_picture "moved, then b (back to rest)" "$tmp/view3.exr" "$tmp/prt.exr" 0.5
  hud_says "moved, then b" "PRT at rest"
  ;;
dynamic_moments)
  # the default representation, moment shadow maps (dyn's --order asks for
  # CSM): the viewer's moved frame against relight-dynamic's, and its HUD
  # names the moments' stages
  dyn_scene
  mom=(--sky --lights 4 --shadow-res 64 --shadow moments)
  mv=(--move object:3,0,2)
  "$bin" relight-dynamic "$data/bunny_lowres.obj" --ground "${mom[@]}" "${dcam[@]}" "${mv[@]}" -q -o "$tmp/rd.exr" ||
    fail "relight-dynamic --shadow moments"
  view --dynamic "$tmp/d.hlt" "${mom[@]}" "${dcam[@]}" "${mv[@]}" --no-glare --frames 2 --screenshot "$tmp/view.exr" ||
    fail "view --dynamic --shadow moments exited with an error"
  same_picture "--dynamic --shadow moments, object moved by 3,0,2" "$tmp/view.exr" "$tmp/rd.exr" 0.5
  hud_says "--dynamic --shadow moments, object moved" "dynamic K 4"
  grep -i "moment" "$tmp/view.txt" | head -n 3
  grep -qi "moment" "$tmp/view.txt" || fail "the viewer's report does not name the moment shadow maps"
  ;;
dynamic_drag)
  dyn_scene
  # from the bunny's flank (pixel 130,100) to the left and down
  view --dynamic "$tmp/d.hlt" "${dyn[@]}" "${dcam[@]}" --drag 130,100,90,115 --no-glare --frames 2 \
    --screenshot "$tmp/view.exr" || fail "view --dynamic --drag exited with an error"
  tr=$(sed -n 's/^view: dragged body "object" to translation \([^ ]*\)$/\1/p' "$tmp/view.txt")
  echo "dragged by: ${tr:-nothing}"
  [ -n "$tr" ] || fail "the drag moved no body"
  # a drag across the ground: horizontal, and far enough to see
  awk -F, -v t="$tr" 'BEGIN { split(t, a, ","); exit !(a[2] == 0 && a[1] * a[1] + a[3] * a[3] > 1) }' ||
    fail "the drag's translation $tr is not horizontal or under 1 unit"
  "$bin" relight-dynamic "$data/bunny_lowres.obj" --ground "${dyn[@]}" "${dcam[@]}" --move "object:$tr" -q \
    -o "$tmp/rd.exr" || fail "relight-dynamic --move object:$tr"
  same_picture "--drag 130,100,90,115" "$tmp/view.exr" "$tmp/rd.exr" 0.5
  hud_says "--drag" "dynamic K 4"
  # the ground is not dragged: a press on it alone finds no body
  view --dynamic "$tmp/d.hlt" "${dyn[@]}" "${dcam[@]}" --drag 20,180,40,180 --frames 1
  rc=$?
  [ $rc -eq 2 ] || fail "a drag starting on the ground: exit $rc, expected 2"
  grep -q "no body under window point 20,180" "$tmp/view.txt" || fail "a drag on the ground: no message naming the pixel"
  ;;
dynamic_anim)
  "${HL_SCENE_GEN:?}" "$tmp/anim.gltf" || fail "viewer_scene"
  acam=(--size 256x192 --exposure -1 --eye 6,6,10 --target 0,0.5,0)
  for t in 0.5 1.5; do
    "$bin" relight-dynamic "$tmp/anim.gltf" "${dyn[@]}" "${acam[@]}" --time $t -q -o "$tmp/rd$t.exr" ||
      fail "relight-dynamic --time $t"
    view --dynamic "$tmp/anim.gltf" "${dyn[@]}" "${acam[@]}" --time $t --no-glare --frames 2 \
      --screenshot "$tmp/view$t.exr" || fail "view --dynamic --time $t exited with an error"
    same_picture "the box at $t s" "$tmp/view$t.exr" "$tmp/rd$t.exr" -1
    hud_says "--time $t" "dynamic K 4: .*, t $t""0 s of 0.00-2.00 paused"
  done
  echo "the box at 0.5 s and at 1.5 s must differ:"
  must_differ "$tmp/view0.5.exr" "$tmp/view1.5.exr" -1 "the frames at 0.5 s and 1.5 s are the same picture: --time did nothing"
  # playing: every frame after the first is a new dynamic frame
  view --dynamic "$tmp/anim.gltf" "${dyn[@]}" "${acam[@]}" --play --no-glare --frames 4 ||
    fail "view --dynamic --play exited with an error"
  hud_says "--play" "of 0.00-2.00 playing"
  grep -q "^  3 frames with a lighting change" "$tmp/view.txt" || fail "--play: not 3 new frames after the first"
  ;;
dynamic_bad)
  [ "${HL_VIEWER_BUILT:-OFF}" = ON ] || skip "haarlight was built without the viewer"
  expect() {
    local name="$1" want="$2" part="$3"; shift 3
    "$bin" view "$@" >"$tmp/out.txt" 2>"$tmp/err.txt"
    local rc=$?
    echo "$name: exit $rc: $(head -c 300 "$tmp/err.txt" | head -1)"
    [ "$rc" -eq "$want" ] || fail "$name: exit code $rc, expected $want"
    grep -q -- "$part" "$tmp/err.txt" || fail "$name: message lacks '$part'"
  }
  scene # ground at 16 quads: not the mesh of bunny_lowres.obj --ground
  obj="$data/bunny_lowres.obj"
  expect missing 1 "nothere.obj" --dynamic "$tmp/nothere.obj"
  expect missing_hlt 1 "nothere.hlt" --dynamic "$tmp/nothere.hlt"
  expect no_scene 2 "no SCENE given" --dynamic
  expect not_dynamic 2 "--lights is an option of --dynamic" "$tmp/s.hlt" --lights 4
  expect lights_zero 2 "--lights" --dynamic "$obj" --lights 0
  expect res_odd 2 "--shadow-res" --dynamic "$obj" --shadow-res 17
  expect order_low 2 "--order" --dynamic "$obj" --order 3
  expect time_negative 2 "--time" --dynamic "$obj" --time -1
  expect time_nan 2 "--time" --dynamic "$obj" --time nan
  expect move_syntax 2 "--move" --dynamic "$obj" --move object
  expect move_nan 2 "--move" --dynamic "$obj" --move object:nan,0,0
  expect move_unknown 2 'no body named "teapot"' --dynamic "$obj" --ground --move teapot:1,0,0
  expect drag_syntax 2 "--drag" --dynamic "$obj" --drag 1,2,3
  expect hlt_twice 2 "is a transport already" --dynamic "$tmp/s.hlt" --hlt "$tmp/s.hlt"
  expect ground_on_hlt 2 "--ground" --dynamic "$tmp/s.hlt" --ground
  expect hlt_other_mesh 1 "not belong to that scene" --dynamic "$obj" --ground --hlt "$tmp/s.hlt"
  ;;
surroundings_capture)
  scene
  for lit in alone sky; do
    extra=(); [ $lit = sky ] && extra=(--sky --sun-elevation 20)
    "$bin" relight "$tmp/s.hlt" "${sur[@]}" "${extra[@]}" "${scam[@]}" -q -o "$tmp/relight.exr" || fail "relight ($lit)"
    # frame 1 with them drawn, then s hides them for frame 2, the screenshot
    view "$tmp/s.hlt" "${sur[@]}" "${extra[@]}" "${scam[@]}" --no-glare --frames 2 --keys s \
      --screenshot "$tmp/view.exr" || fail "view --surroundings ($lit) exited with an error"
    same_picture "surroundings at 0.5 s ($lit), hidden" "$tmp/view.exr" "$tmp/relight.exr" 0.5
    hud_says "surroundings ($lit)" "t 0.50 s of 0.00-4.00 paused, surroundings hidden"
  done
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --no-glare --frames 1 --screenshot "$tmp/drawn.exr" ||
    fail "view --surroundings --frames 1 exited with an error"
  hud_says "surroundings drawn" "capture + relight .* ms, t 0.50 s"
  "$bin" relight "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" -q -o "$tmp/relight.exr" || fail "relight"
  echo "drawn, the lamp and the wall must show:"
  must_differ "$tmp/drawn.exr" "$tmp/relight.exr" 0.5 "the surroundings were not drawn"
  # from above, none of them in view: the first frame itself, at 1.5 s (the lamp at -X)
  top=(--size 256x192 --exposure 0.5 --eye 4,28,14 --target 0,2,1 --fov 26)
  tsur=(--surroundings "$data/surroundings/lamp_orbit.gltf" --time 1.5)
  "$bin" relight "$tmp/s.hlt" "${tsur[@]}" "${top[@]}" -q -o "$tmp/top.exr" || fail "relight from above"
  view "$tmp/s.hlt" "${tsur[@]}" "${top[@]}" --no-glare --frames 1 --screenshot "$tmp/vtop.exr" ||
    fail "view from above exited with an error"
  same_picture "surroundings at 1.5 s, seen from above, first frame" "$tmp/vtop.exr" "$tmp/top.exr" 0.5
  "$bin" relight "$tmp/s.hlt" "${sur[@]}" "${top[@]}" -q -o "$tmp/top05.exr" || fail "relight from above at 0.5 s"
  echo "the lamp at 1.5 s must not light the bunny as at 0.5 s:"
  must_differ "$tmp/vtop.exr" "$tmp/top05.exr" 0.5 "--time did not move the lamp's light"
  # more capture points: the viewer's picture is relight's with the same points
  "$bin" relight "$tmp/s.hlt" "${tsur[@]}" "${top[@]}" --probes 8 -q -o "$tmp/top8.exr" || fail "relight --probes 8"
  view "$tmp/s.hlt" "${tsur[@]}" "${top[@]}" --probes 8 --no-glare --frames 1 --screenshot "$tmp/vtop8.exr" ||
    fail "view --probes 8 exited with an error"
  same_picture "surroundings at 1.5 s from 8 capture points, seen from above" "$tmp/vtop8.exr" "$tmp/top8.exr" 0.5
  echo "8 capture points must not light the ground as one does:"
  must_differ "$tmp/vtop8.exr" "$tmp/top.exr" 0.5 "--probes 8 gave the one point's picture"
  ;;
surroundings_drag)
  scene
  "$bin" relight "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" -q -o "$tmp/relight.exr" || fail "relight"
  # the lamp is at pixel 237,40 at 0.5 s; dragged towards the camera's left
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --no-glare --drag 237,40,150,60 --frames 2 --keys s \
    --screenshot "$tmp/dragged.exr" || fail "view --drag exited with an error"
  tr=$(sed -n 's/^view: dragged body "lamp" of the surroundings to translation \([^ ]*\)$/\1/p' "$tmp/view.txt")
  echo "lamp dragged by: ${tr:-nothing}"
  [ -n "$tr" ] || fail "the drag did not move the lamp"
  awk -F, -v t="$tr" 'BEGIN { split(t, a, ","); exit !(a[2] == 0 && a[1] * a[1] + a[3] * a[3] > 1) }' ||
    fail "the lamp's translation $tr is not horizontal or under 1 unit"
  hud_says "--drag" "1 body moved"
  echo "the object under the dragged lamp must not look as under the lamp in place:"
  must_differ "$tmp/dragged.exr" "$tmp/relight.exr" 0.5 "dragging the lamp did not change the lighting"
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --no-glare --drag 237,40,150,60 --frames 2 --keys bs \
    --screenshot "$tmp/back.exr" || fail "view --drag --keys bs exited with an error"
  same_picture "dragged, then b (the lamp back)" "$tmp/back.exr" "$tmp/relight.exr" 0.5
  # a press on the bunny, which stands in front of the wall: nothing grabbed
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --drag 100,120,150,60 --frames 1
  rc=$?
  [ $rc -eq 2 ] || fail "a drag starting on the object: exit $rc, expected 2"
  grep -q "no body of the surroundings under window point 100,120" "$tmp/view.txt" ||
    fail "a drag starting on the object: no message naming the pixel"
  ;;
surroundings_unchanged)
  scene
  # b with nothing moved asks for lighting; the relighter finds the same triangles
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --no-glare --frames 2 --keys b || fail "view --keys b"
  hud_says "b, nothing moved" "lighting: unchanged, t 0.50 s"
  grep -q "surroundings: 1 captures with relight (mean .* ms); 1 frames found them and the map unchanged" \
    "$tmp/view.txt" || fail "b with nothing moved: not 1 capture and 1 unchanged frame"
  grep -q "frames with a lighting change" "$tmp/view.txt" && fail "b with nothing moved counted a lighting change"
  # playing: a capture every frame
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --no-glare --frames 3 --play || fail "view --play"
  hud_says "--play" "capture + relight .* ms, t .* s of 0.00-4.00 playing"
  grep -q "surroundings: 3 captures with relight (mean .* ms); 0 frames" "$tmp/view.txt" ||
    fail "--play: not a capture every frame"
  # space after frame 1: plays (frames 2 and 3 captured) ...
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --no-glare --frames 3 --keys ' ' || fail "view --keys space"
  hud_says "space" "t .* s of 0.00-4.00 playing"
  grep -q "surroundings: 3 captures with relight" "$tmp/view.txt" || fail "space: the animation did not play"
  # ... and pauses: frame 2 asks at the time of frame 1 and finds nothing changed
  view "$tmp/s.hlt" "${sur[@]}" "${scam[@]}" --no-glare --frames 3 --play --keys ' ' || fail "view --play --keys space"
  hud_says "--play, space" "lighting: unchanged, t .* s of 0.00-4.00 paused"
  grep -q "surroundings: 1 captures with relight (mean .* ms); 1 frames found them and the map unchanged" \
    "$tmp/view.txt" || fail "--play, space: the paused frames were not found unchanged"
  ;;
textured)
  box="$(cd "$(dirname "$0")" && pwd)/data/textured_box.gltf"
  "$bin" precompute "$box" --ground --ground-res 16 -C 16 -N 16 -q -o "$tmp/t.hlt" || fail "precompute"
  cam=(--size 320x240 --exposure 0.5 --eye 3,2.5,4 --target 0,0.6,0)
  "$bin" relight "$tmp/t.hlt" --sky --textures "$box" "${cam[@]}" -q -o "$tmp/relight.exr" || fail "relight --textures"
  "$bin" relight "$tmp/t.hlt" --sky "${cam[@]}" -q -o "$tmp/plain.exr" || fail "relight"
  view "$tmp/t.hlt" --textures "$box" "${cam[@]}" --no-glare --frames 3 --screenshot "$tmp/view.exr" ||
    fail "view --textures exited with an error"
  same_picture "the textured box" "$tmp/view.exr" "$tmp/relight.exr" 0.5
  must_differ "$tmp/plain.exr" "$tmp/relight.exr" 0.5 "the texture changed nothing in relight's picture"
  ;;
surroundings_bad)
  [ "${HL_VIEWER_BUILT:-OFF}" = ON ] || skip "haarlight was built without the viewer"
  expect() {
    local name="$1" want="$2" part="$3"; shift 3
    "$bin" view "$@" >"$tmp/out.txt" 2>"$tmp/err.txt"
    local rc=$?
    echo "$name: exit $rc: $(grep -v '^DBG' "$tmp/err.txt" | head -c 300 | head -1)"
    [ "$rc" -eq "$want" ] || fail "$name: exit code $rc, expected $want"
    grep -q -- "$part" "$tmp/err.txt" || fail "$name: message lacks '$part'"
  }
  scene
  printf 'not a mesh\n' >"$tmp/text.gltf"
  expect missing 1 "nothere.gltf" "$tmp/s.hlt" --surroundings "$tmp/nothere.gltf"
  expect not_a_mesh 1 "text.gltf" "$tmp/s.hlt" --surroundings "$tmp/text.gltf"
  expect time_negative 2 "--time -1" "$tmp/s.hlt" --surroundings "${sur[1]}" --time -1
  expect time_nan 2 "--time nan" "$tmp/s.hlt" --surroundings "${sur[1]}" --time nan
  expect time_alone 2 "--time needs --surroundings" "$tmp/s.hlt" --time 1
  expect play_alone 2 "--play is an option of --surroundings or --dynamic" "$tmp/s.hlt" --play
  expect with_dynamic 2 "not --dynamic" --dynamic "$tmp/s.hlt" --surroundings "${sur[1]}"
  expect no_value 2 "needs a value" "$tmp/s.hlt" --surroundings
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
*) echo "usage: $0 capture_sky|capture_env|drop|bad_input|dynamic_rest|dynamic_moved|dynamic_drag|dynamic_anim|dynamic_bad|surroundings_capture|surroundings_drag|surroundings_unchanged|surroundings_bad"; exit 2 ;;
esac
[ "$fails" -eq 0 ] && echo "passed" || { echo "$fails failure(s)"; exit 1; }
