#!/usr/bin/env bash
# Installs Antumbra's C library under $DESTDIR$PREFIX (make install):
#   include/antumbra.h
#   lib/libantumbra.a, lib/libantumbra.so.X.Y.Z with its soname and development links
#   lib/pkgconfig/antumbra.pc (+ antumbra-libdir.pc, see the comment in antumbra.pc)
#   lib/cmake/antumbra/antumbraConfig.cmake and antumbraConfigVersion.cmake
# The system libraries that the static archive needs are the ones rustc prints
# while building it, so the .pc and CMake files always match the archive.
set -euo pipefail
cd "$(dirname "$0")/.."

prefix=${PREFIX:-/usr/local}
destdir=${DESTDIR:-}
cargo=${CARGO:-cargo}
target_dir=${CARGO_TARGET_DIR:-$PWD/target}
case "$prefix" in
  /*) ;;
  *) echo "install: PREFIX must be an absolute path, not '$prefix'" >&2; exit 2 ;;
esac

version=$(sed -n '/^\[workspace.package\]/,/^\[/s/^version = "\(.*\)"/\1/p' Cargo.toml)
IFS=. read -r major minor _patch <<<"$version"
if [ "$major" = 0 ]; then soname="libantumbra.so.0.$minor"; else soname="libantumbra.so.$major"; fi
url=$(sed -n '/^\[workspace.package\]/,/^\[/s/^repository = "\(.*\)"/\1/p' Cargo.toml)

# One compile gives both libraries and the static archive's native libraries.
log=$(mktemp)
trap 'rm -f "$log"' EXIT
if ! "$cargo" rustc --release -p antumbra-ffi --crate-type staticlib,cdylib \
    -- --print native-static-libs >"$log" 2>&1; then
  cat "$log" >&2
  exit 1
fi
native=$(sed -n 's/.*native-static-libs: //p' "$log" | tail -n 1)
if [ -z "$native" ]; then
  echo "install: rustc did not print the static library's native libraries" >&2
  exit 1
fi
cmake_native=$(sed -e 's/-l//g' -e 's/ /;/g' <<<"$native")

root="$destdir$prefix"
lib="$root/lib"
install -d "$root/include" "$lib/pkgconfig" "$lib/cmake/antumbra" "$lib/antumbra/static"
install -m 644 include/antumbra.h "$root/include/antumbra.h"
install -m 644 "$target_dir/release/libantumbra.a" "$lib/libantumbra.a"
install -m 755 "$target_dir/release/libantumbra.so" "$lib/libantumbra.so.$version"
ln -sfn "libantumbra.so.$version" "$lib/$soname"
ln -sfn "$soname" "$lib/libantumbra.so"
# The directory that `pkg-config --static` puts first holds only the archive.
ln -sfn ../../libantumbra.a "$lib/antumbra/static/libantumbra.a"

fill() {
  sed -e "s|@PREFIX@|$prefix|g" -e "s|@VERSION@|$version|g" \
      -e "s|@VERSION_MAJOR@|$major|g" -e "s|@VERSION_MINOR@|$minor|g" \
      -e "s|@SONAME@|$soname|g" -e "s|@URL@|$url|g" \
      -e "s|@NATIVE_STATIC_LIBS@|$native|g" -e "s|@CMAKE_NATIVE_LIBS@|$cmake_native|g" \
      "ffi/install/$1.in" >"$2"
  chmod 644 "$2"
}
fill antumbra.pc "$lib/pkgconfig/antumbra.pc"
fill antumbra-libdir.pc "$lib/pkgconfig/antumbra-libdir.pc"
fill antumbraConfig.cmake "$lib/cmake/antumbra/antumbraConfig.cmake"
fill antumbraConfigVersion.cmake "$lib/cmake/antumbra/antumbraConfigVersion.cmake"

echo "installed Antumbra $version under $root (soname $soname)"
