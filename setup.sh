#!/usr/bin/env bash
# setup.sh - install what haarlight needs from Debian, build it, and run
# the demo or the tests.
#
#   ./setup.sh demo    the built-in default scene (bunny on a ground plane):
#                      precompute, then relight under the procedural sun and
#                      sky, under data/city.exr and under a lamp carried
#                      around it, writing build/demo-*.png
#   ./setup.sh test    run the test suite (ctest, on PoCL's CPU device), then
#                      the same under ASan + UBSan (build-asan/), then a short
#                      libFuzzer pass (build-fuzz/); also installs
#                      assimp-testmodels, the model files one test loads
#   ./setup.sh build   only install and build
#
# Packages are installed with apt-get only when missing (as root, or through
# sudo). The build goes to ./build.
set -euo pipefail
cd "$(dirname "$0")"

what="${1:-build}"
case "$what" in demo|test|build) ;; *) echo "usage: $0 demo|test|build" >&2; exit 2 ;; esac

packages=(build-essential cmake pkg-config
          pocl-opencl-icd ocl-icd-opencl-dev opencl-headers clinfo
          libembree-dev libopenexr-dev libpng-dev libglfw3-dev libxrandr-dev libassimp-dev libstb-dev gnuplot-nox help2man
          libgl1-mesa-dev libgl1-mesa-dri xvfb xauth valgrind
          clang libclang-rt-14-dev)
# only `./setup.sh test` needs these: the model files of assimp's own test
# suite, which hl.assimp_models.testmodels loads one by one; Slurm and
# MUNGE, for hl.slurm.array (it runs its own one-node cluster: its own
# daemons, config and key, not the system's)
test_packages=(assimp-testmodels slurm-wlm munge)
if [ "$what" = test ]; then packages+=("${test_packages[@]}"); fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

jobs="$(nproc 2>/dev/null || echo 2)"
# the viewer (`haarlight view`) is built; its tests open windows under Xvfb
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DHL_WITH_VIEWER=ON
cmake --build build -j"$jobs"

case "$what" in
  demo)
    ./build/haarlight precompute data/bunny_lowres.obj --ground -o build/demo.hlt
    ./build/haarlight info build/demo.hlt
    ./build/haarlight relight build/demo.hlt --sky -o build/demo-sky.png
    ./build/haarlight relight build/demo.hlt --env data/city.exr -o build/demo-city.png
    ./build/haarlight relight build/demo.hlt --sky -o build/demo-sky.ply
    # the dynamic method, no precompute: the bunny lifted and carried across
    # its ground, its shadow following, from a fixed camera
    i=0
    for x in -2.5 0 2.5; do
      ./build/haarlight relight-dynamic data/bunny_lowres.obj --ground --sky --move "object:$x,2,0" \
          --eye 0,16,30 --target 0,2,0 --size 400x300 -o "build/demo-dynamic-$i.png"
      i=$((i + 1))
    done
    # lighting captured from the surroundings: a lamp carried around the
    # bunny (the file's animation at 0 s and 2 s), the shadow opposite it
    for t in 0 2; do
      ./build/haarlight relight build/demo.hlt --surroundings data/surroundings/lamp_orbit.gltf --time "$t" \
          --exposure 0 --size 400x300 -o "build/demo-lamp-$t.png"
    done
    echo "demo: wrote build/demo-sky.png, build/demo-city.png, build/demo-sky.ply, build/demo-dynamic-{0,1,2}.png" \
         "and build/demo-lamp-{0,2}.png"
    ;;
  test)
    # 1. the suite (valgrind memcheck of a small scene included)
    (cd build && ctest --output-on-failure)
    # 2. the suite again under AddressSanitizer and UndefinedBehaviorSanitizer
    #    (the viewer's tests are left out: Mesa's own allocations are not ours);
    #    it runs on the kernel cache step 1 filled: LeakSanitizer crashes at
    #    exit in a process where PoCL compiled a kernel (docs/ARCHITECTURE.md)
    cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHL_SANITIZE=ON -DHL_WITH_VIEWER=OFF
    cmake --build build-asan -j"$jobs"
    (cd build-asan && ctest --output-on-failure -j"$jobs")
    # 3. a short fuzz pass (20 s a target, fixed seed) and the crash
    #    regressions; tests/fuzz/run_long.sh runs a long one
    CC=clang cmake -S . -B build-fuzz -DHL_FUZZ=ON -DHL_WITH_VIEWER=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo
    cmake --build build-fuzz -j"$jobs" --target fuzz_transport fuzz_mesh fuzz_env
    (cd build-fuzz && ctest -L fuzz --output-on-failure)
    ;;
esac
