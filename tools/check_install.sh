#!/usr/bin/env bash
# make install-check: installs Antumbra into a fresh temporary prefix and builds
# programs against it as an engine would, then runs them:
#   - c_examples/cmake_consumer (C++17) through find_package, once with
#     antumbra::antumbra (shared) and once with antumbra::antumbra_static;
#   - the same program through `pkg-config --cflags --libs antumbra`, and through
#     `pkg-config --cflags --static --libs antumbra`;
#   - c_examples/ambient_occlusion.c (C99) through `pkg-config --static`, no other flag;
#   - a DESTDIR install: the files land under DESTDIR, the paths inside name PREFIX.
# A shared build must load libantumbra.so by its soname; a static one must not load it.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
cmake=${CMAKE:-cmake}
cxx=${CXX:-g++}
cc=${CC:-gcc}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"
passed=0

fail() { echo "install-check: $*" >&2; exit 1; }
ok() { echo "[install-check] $*: ok"; passed=$((passed + 1)); }
logged() { # logged NAME COMMAND...: runs the command, showing its output only when it fails
  local log="$work/$1.log"; shift
  "$@" >"$log" 2>&1 || { cat "$log" >&2; fail "'$*' failed"; }
}

version=$(sed -n '/^\[workspace.package\]/,/^\[/s/^version = "\(.*\)"/\1/p' Cargo.toml)
IFS=. read -r major minor _patch <<<"$version"
if [ "$major" = 0 ]; then soname="libantumbra.so.0.$minor"; else soname="libantumbra.so.$major"; fi

needs_shared() { readelf -d "$1" | grep -q "NEEDED.*\[$soname\]" || fail "$1 does not load $soname"; }
needs_no_shared() { ! readelf -d "$1" | grep -q 'NEEDED.*libantumbra' || fail "$1 loads libantumbra.so"; }

logged install env PREFIX="$prefix" ./tools/install.sh
for file in include/antumbra.h lib/libantumbra.a "lib/libantumbra.so.$version" "lib/$soname" \
    lib/libantumbra.so lib/pkgconfig/antumbra.pc lib/cmake/antumbra/antumbraConfig.cmake \
    lib/cmake/antumbra/antumbraConfigVersion.cmake; do
  [ -e "$prefix/$file" ] || fail "make install did not install $file"
done
[ "$(readlink "$prefix/lib/libantumbra.so")" = "$soname" ] || fail "libantumbra.so does not point to $soname"
readelf -d "$prefix/lib/libantumbra.so.$version" | grep -q "SONAME.*\[$soname\]" \
  || fail "libantumbra.so.$version has no soname $soname"
cmp -s include/antumbra.h "$prefix/include/antumbra.h" || fail "the installed header differs"
ok "make install PREFIX=<tmp> (soname $soname)"

for target in antumbra::antumbra antumbra::antumbra_static; do
  build="$work/cmake-${target#antumbra::}"
  logged "configure-${target#antumbra::}" "$cmake" -S c_examples/cmake_consumer -B "$build" \
    -DCMAKE_PREFIX_PATH="$prefix" -DANTUMBRA_TARGET="$target" -DCMAKE_BUILD_TYPE=Release
  logged "build-${target#antumbra::}" "$cmake" --build "$build"
  if [ "$target" = antumbra::antumbra ]; then needs_shared "$build/consumer"; else needs_no_shared "$build/consumer"; fi
  "$build/consumer" || fail "the CMake consumer linked with $target failed"
  ok "CMake find_package, $target"
done

export PKG_CONFIG_PATH="$prefix/lib/pkgconfig"
logged pc-shared "$cxx" -std=c++17 -O2 c_examples/cmake_consumer/consumer.cpp \
  $(pkg-config --cflags --libs antumbra) -Wl,-rpath,"$prefix/lib" -o "$work/pc-shared"
needs_shared "$work/pc-shared"
"$work/pc-shared" || fail "the pkg-config consumer (shared) failed"
ok "pkg-config --cflags --libs antumbra"

logged pc-static "$cxx" -std=c++17 -O2 c_examples/cmake_consumer/consumer.cpp \
  $(pkg-config --cflags --static --libs antumbra) -o "$work/pc-static"
needs_no_shared "$work/pc-static"
"$work/pc-static" || fail "the pkg-config consumer (static) failed"
ok "pkg-config --cflags --static --libs antumbra (C++)"

logged pc-c "$cc" -std=c99 c_examples/ambient_occlusion.c $(pkg-config --cflags --static --libs antumbra) \
  -o "$work/ao-static"
needs_no_shared "$work/ao-static"
(cd "$work" && ./ao-static "$work/ao.pgm" >"$work/ao.log") || { cat "$work/ao.log" >&2; fail "ambient_occlusion failed"; }
ok "pkg-config --static, a C program with no other flag"

logged destdir env DESTDIR="$work/stage" PREFIX=/opt/antumbra ./tools/install.sh
[ -e "$work/stage/opt/antumbra/lib/libantumbra.a" ] || fail "DESTDIR install missing lib/libantumbra.a"
grep -qx 'prefix=/opt/antumbra' "$work/stage/opt/antumbra/lib/pkgconfig/antumbra.pc" \
  || fail "DESTDIR install's antumbra.pc does not name prefix /opt/antumbra"
if grep -rq "$work/stage" "$work/stage/opt/antumbra/lib/pkgconfig" "$work/stage/opt/antumbra/lib/cmake"; then
  fail "DESTDIR leaked into the installed files"
fi
ok "make install DESTDIR=<tmp> PREFIX=/opt/antumbra"

echo "install-check: $passed passed, 0 failed"
