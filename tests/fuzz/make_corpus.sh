#!/usr/bin/env bash
# make_corpus.sh [HAARLIGHT] - regenerates the seed corpora in corpus/.
#
# Every seed is made here by the project itself (hand-written meshes, and
# transport files and OpenEXR maps written by the haarlight command), so the
# corpus carries no third-party data. HAARLIGHT defaults to build/haarlight.
#
#   corpus/mesh/       one selector byte ('0' .obj, '1' .ply, '2' .off,
#                      '3' .stl, '4' .gltf, '5' .glb: see fuzz_mesh.c), then
#                      the file's bytes
#   corpus/transport/  transport files of tiny meshes (-N 8 -C 8)
#   corpus/env/        small equirectangular OpenEXR maps: images written by
#                      the haarlight command (ZIP, float RGB: read with
#                      OpenEXRCore), a copy of tests/data/float_tiled.exr
#                      (tiled float: read through half floats), and
#                      cube_*_half.exr (ZIP, half RGB, written by the command
#                      before it wrote floats; kept, not regenerated here)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
bin="${1:-$here/../../build/haarlight}"
[ -x "$bin" ] || { echo "make_corpus: $bin is not an executable (build the project first)" >&2; exit 2; }
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
out="$here/corpus"
rm -rf "$out/mesh" "$out/transport"
find "$out/env" -name '*.exr' ! -name '*_half.exr' -delete 2>/dev/null || true
mkdir -p "$out/mesh" "$out/transport" "$out/env"

# seed SELECTOR NAME FILE: the mesh seed is the selector byte then FILE.
seed() { { printf '%s' "$1"; cat "$3"; } >"$out/mesh/$2"; }

cat >"$tmp/cube.obj" <<'EOF'
# unit cube, quads, outward winding
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
EOF
cat >"$tmp/tetra_normals.obj" <<'EOF'
o tetra
v 0 0 0 1 0 0
v 1 0 0 0 1 0
v 0 1 0 0 0 1
v 0 0 1 0.5 0.5 0.5
vn 0 0 -1
vn 0 -1 0
vn -1 0 0
vn 0.577 0.577 0.577
vt 0 0
vt 1 0
vt 0 1
g faces
usemtl none
f 1/1/1 3/3/1 2/2/1
f 1/1/2 2/2/2 4/3/2
f -4/1/3 -1/3/3 -2/2/3
f 2//4 3//4 4//4
l 1 2
EOF
cat >"$tmp/tetra_ascii.ply" <<'EOF'
ply
format ascii 1.0
comment tetrahedron with vertex colours
element vertex 4
property float x
property float y
property float z
property uchar red
property uchar green
property uchar blue
element face 4
property list uchar int vertex_indices
end_header
0 0 0 255 0 0
1 0 0 0 255 0
0 1 0 0 0 255
0 0 1 128 128 128
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
EOF
cat >"$tmp/tetra.off" <<'EOF'
OFF
4 4 6
0 0 0
1 0 0
0 1 0
0 0 1
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
EOF
cat >"$tmp/tetra.stl" <<'EOF'
solid tetra
facet normal 0 0 -1
 outer loop
  vertex 0 0 0
  vertex 0 1 0
  vertex 1 0 0
 endloop
endfacet
facet normal 0 -1 0
 outer loop
  vertex 0 0 0
  vertex 1 0 0
  vertex 0 0 1
 endloop
endfacet
facet normal -1 0 0
 outer loop
  vertex 0 0 0
  vertex 0 0 1
  vertex 0 1 0
 endloop
endfacet
facet normal 0.577 0.577 0.577
 outer loop
  vertex 1 0 0
  vertex 0 1 0
  vertex 0 0 1
 endloop
endfacet
endsolid tetra
EOF
# Binary files from their little-endian fields (printf octal escapes).
le32() { local v=$1; printf "\\$(printf %03o $((v & 255)))\\$(printf %03o $(((v >> 8) & 255)))\\$(printf %03o $(((v >> 16) & 255)))\\$(printf %03o $(((v >> 24) & 255)))"; }
f32() { # the float's bit pattern, for the few values used here
  case "$1" in 0) le32 0 ;; 1) le32 1065353216 ;; -1) le32 3212836864 ;; *) echo "f32: $1" >&2; exit 2 ;; esac; }
{
  printf 'ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n'
  printf 'element face 2\nproperty list uchar uint vertex_indices\nend_header\n'
  for p in "0 0 0" "1 0 0" "1 1 0" "0 1 0"; do for c in $p; do f32 "$c"; done; done
  printf '\003'; le32 0; le32 1; le32 2
  printf '\003'; le32 0; le32 2; le32 3
} >"$tmp/quad_binary.ply"
{
  head -c 80 /dev/zero | tr '\0' ' '
  le32 2
  for tri in "0 0 1|0 0 0|1 0 0|1 1 0" "0 0 1|0 0 0|1 1 0|0 1 0"; do
    IFS='|' read -r n a b c <<<"$tri"
    for p in "$n" "$a" "$b" "$c"; do for x in $p; do f32 "$x"; done; done
    printf '\000\000'
  done
} >"$tmp/quad_binary.stl"
# glTF 2.0 with an embedded buffer: a triangle (3 float3 positions, 36
# bytes) and its indices (3 uint16, 6 bytes, padded to 8).
buf="$( { for p in "0 0 0" "1 0 0" "0 1 0"; do for c in $p; do f32 "$c"; done; done; printf '\000\000\001\000\002\000\000\000'; } | base64 -w0)"
cat >"$tmp/triangle.gltf" <<EOF
{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
"meshes":[{"primitives":[{"attributes":{"POSITION":1},"indices":0}]}],
"buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,$buf"}],
"bufferViews":[{"buffer":0,"byteOffset":36,"byteLength":6,"target":34963},
{"buffer":0,"byteOffset":0,"byteLength":36,"target":34962}],
"accessors":[{"bufferView":0,"componentType":5123,"count":3,"type":"SCALAR"},
{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3","max":[1,1,0],"min":[0,0,0]}]}
EOF
# The same triangle as binary glTF: header, JSON chunk, BIN chunk.
json='{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":1},"indices":0}]}],"buffers":[{"byteLength":44}],"bufferViews":[{"buffer":0,"byteOffset":36,"byteLength":6},{"buffer":0,"byteOffset":0,"byteLength":36}],"accessors":[{"bufferView":0,"componentType":5123,"count":3,"type":"SCALAR"},{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3","max":[1,1,0],"min":[0,0,0]}]}'
while [ $(( ${#json} % 4 )) -ne 0 ]; do json="$json "; done
{
  printf 'glTF'; le32 2; le32 $((12 + 8 + ${#json} + 8 + 44))
  le32 ${#json}; printf 'JSON'; printf '%s' "$json"
  le32 44; printf 'BIN\000'
  for p in "0 0 0" "1 0 0" "0 1 0"; do for c in $p; do f32 "$c"; done; done
  printf '\000\000\001\000\002\000\000\000'
} >"$tmp/triangle.glb"

seed 0 cube_obj "$tmp/cube.obj"
seed 0 tetra_normals_obj "$tmp/tetra_normals.obj"
seed 1 tetra_ascii_ply "$tmp/tetra_ascii.ply"
seed 1 quad_binary_ply "$tmp/quad_binary.ply"
seed 2 tetra_off "$tmp/tetra.off"
seed 3 tetra_ascii_stl "$tmp/tetra.stl"
seed 3 quad_binary_stl "$tmp/quad_binary.stl"
seed 4 triangle_gltf "$tmp/triangle.gltf"
seed 5 triangle_glb "$tmp/triangle.glb"

# Transport files: both quantisation schemes and truncation rules.
"$bin" precompute "$tmp/cube.obj" -o "$out/transport/cube_log8_energy" -N 8 -C 8 --device ref -q
"$bin" precompute "$tmp/tetra.off" -o "$out/transport/tetra_linear8_top16" -N 8 -C 8 --device ref -q \
  --quant linear8 --terms 16
"$bin" precompute "$tmp/quad_binary.ply" -o "$out/transport/quad_ground_all" -N 8 -C 8 --device ref -q \
  --ground --ground-res 2 --terms all

# Environment maps: the built-in sky and an image of the cube under it.
"$bin" relight "$out/transport/cube_log8_energy" --sky -o "$out/env/cube_16x8.exr" --size 16x8 \
  --device ref -q
"$bin" relight "$out/transport/cube_log8_energy" --sky -o "$out/env/cube_4x2.exr" --size 4x2 \
  --device ref -q --eye 3,2,3
"$bin" relight "$out/transport/cube_log8_energy" --sky -o "$out/env/cube_2x1.exr" --size 2x1 \
  --device ref -q
cp "$here/../data/float_tiled.exr" "$out/env/float_tiled.exr"

ls -l "$out"/*/
