#!/bin/bash
# hl.install.<how>: installs the build into a new prefix, then builds and
# runs tests/install/example.c against it, found through CMake's
# find_package (how = cmake) or through pkg-config (how = pkgconfig). The
# program must run, print a lit ground and a lit roof, and write nothing
# but its own transport file.
# Usage: test_install.sh cmake|pkgconfig BUILD_DIR SOURCE_DIR
set -u
how="$1" build="$2" src="$3"
tmp="$(mktemp -d "${HL_TMP:-/tmp}/install.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
cmake --install "$build" --prefix "$tmp/prefix" >"$tmp/install.log" 2>&1 || { cat "$tmp/install.log"; fail "cmake --install"; }
for f in bin/haarlight include/haarlight.h lib/cmake/haarlight/haarlightConfig.cmake lib/pkgconfig/haarlight.pc; do
  [ -e "$tmp/prefix/$f" ] || fail "the install lacks $f"
done
so="$(ls "$tmp"/prefix/lib*/libhaarlight.so.0 "$tmp"/prefix/lib/*/libhaarlight.so.0 2>/dev/null | head -1)"
[ -n "$so" ] || fail "the install lacks libhaarlight.so.0"
objdump -p "$so" | grep -q 'SONAME *libhaarlight.so.0' || fail "$so has no SONAME libhaarlight.so.0"
# the installed header must stand alone: nothing of the library's private headers
grep -q '#include "' "$tmp/prefix/include/haarlight.h" && fail "haarlight.h includes a private header"
case "$how" in
cmake)
  cmake -S "$src/tests/install/consumer" -B "$tmp/b" -DCMAKE_PREFIX_PATH="$tmp/prefix" \
        -DEXAMPLE_SOURCE="$src/tests/install/example.c" >"$tmp/cfg.log" 2>&1 || { cat "$tmp/cfg.log"; fail "configuring the example"; }
  cmake --build "$tmp/b" >"$tmp/build.log" 2>&1 || { cat "$tmp/build.log"; fail "building the example with CMake"; }
  exe="$tmp/b/example"
  ;;
pkgconfig)
  pcdir="$(dirname "$(find "$tmp/prefix" -name haarlight.pc | head -1)")"
  flags="$(PKG_CONFIG_PATH="$pcdir" pkg-config --cflags --libs haarlight)" || fail "pkg-config haarlight"
  echo "pkg-config: $flags"
  # shellcheck disable=SC2086
  cc -std=c11 -Wall -Wextra -Werror -o "$tmp/example" "$src/tests/install/example.c" $flags >"$tmp/build.log" 2>&1 ||
    { cat "$tmp/build.log"; fail "building the example with pkg-config's flags"; }
  exe="$tmp/example"
  ;;
*) fail "usage: $0 cmake|pkgconfig BUILD_DIR SOURCE_DIR" ;;
esac
mkdir -p "$tmp/run"
out="$(cd "$tmp/run" && LD_LIBRARY_PATH="$(dirname "$so")" "$exe" 2>&1)" || fail "the example failed: $out"
echo "example: $out"
# ground corner (lit by sun and sky) and roof: both must be lit and finite
echo "$out" | awk '{ for (i = 3; i <= 5; i++) if (!($i > 0.01)) exit 1; for (i = 7; i <= 9; i++) if (!($i > 0.01)) exit 1 }' ||
  fail "the colours are not all lit: $out"
[ "$(ls "$tmp/run")" = "example.hlt" ] || fail "the example left $(ls "$tmp/run")"
echo "installed and used through $how: passed"
