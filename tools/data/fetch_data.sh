#!/usr/bin/env bash
# Reproduce the third-party test data in tests/data/ from scratch, in a temp dir,
# and check it byte for byte against pinned sha256 sums. See tests/data/SOURCES.md.
#
# Usage: tools/data/fetch_data.sh            # rebuild in a temp dir, verify, then delete it
#        KEEP=1 tools/data/fetch_data.sh     # keep the temp dir (path is printed)
#        tools/data/fetch_data.sh --install  # also copy the rebuilt files into tests/data/
#
# Needs: node + npm (npm registry), apt-get + dpkg-deb (Debian bookworm archive;
# run `apt-get update` once first), python3, tar, sha256sum.
# As root, apt-get may warn "Download is performed unsandboxed as root": harmless.
# Exits non-zero if any download, any rebuilt file or any committed file does not match.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../.." && pwd)
data="$root/tests/data"

# Inputs (pinned).
BUNNY=bunny@1.0.1
TEAPOT=teapot@1.0.0
DEB_PKG=blender-data
DEB_VER=3.4.1+dfsg-2
EXR=sunrise.exr
EXR_DIR=usr/share/blender/datafiles/studiolights/world
CGAL_PKG=libcgal-demo
CGAL_VER=5.5.1-2
CGAL_TGZ=usr/share/doc/libcgal-dev/data.tar.gz
ARMADILLO_OFF=data/meshes/armadillo.off
# Header comments of armadillo.obj (part of the committed bytes).
ARMADILLO_SRC="Stanford Armadillo from Debian $CGAL_PKG $CGAL_VER (source package cgal): $CGAL_TGZ, member $ARMADILLO_OFF"
ARMADILLO_CREDIT="Credit: Stanford Computer Graphics Laboratory (Stanford 3D Scanning Repository, http://graphics.stanford.edu/data/3Dscanrep/). Research use; not for commercial use without their permission. See tests/data/SOURCES.md"

# sha256 of the downloads.
SUM_BUNNY_TGZ=381e02c74b98cf18814d7bec794726ef70b9c67e037273e82054d0043f6ae303
SUM_TEAPOT_TGZ=ebe7143533ff1a35ea25738b43112d36fd9ae072652bde9b2144057e7218890f
SUM_DEB=5ceaf56a49ba3ded95c751d739aeec3d19e7fad76fba5cb70666986af9303b0e
SUM_CGAL_DEB=78b09b23d4d6d1bf15552a1060b419ab3fc09918486462faed197e5fc6ac3735
# sha256 of the OFF inside the CGAL data tarball (the converter's input).
SUM_ARMADILLO_OFF=6f7f3ca1abc506569466b72f2f59d49493a284e7376d7a7e23c08115ec8cec4e
# sha256 of the committed files in tests/data/.
SUM_BUNNY_OBJ=5d2d52d32a03db4a568d87f3dfb4010c30a7945c4b56e079c8a25aae94d94d40
SUM_TEAPOT_OBJ=4bdd18062aa64d278d505635e8e6b2a68f77873f31596bc24ba0280ba9834d9c
SUM_EXR=b97206217e29763d62d9a65ad2d7058460acfb4824659e7a59f5bde374f21937
SUM_ARMADILLO_OBJ=e5da4bcc30f2c054ad3e86ce84d982d2cd67b7690ae7d7a1b78d28122bb24566

install=0
case "${1:-}" in
  --install) install=1 ;;
  "") ;;
  *) echo "usage: $0 [--install]" >&2; exit 2 ;;
esac

work=$(mktemp -d)
if [ -z "${KEEP:-}" ]; then trap 'rm -rf "$work"' EXIT; else echo "work dir: $work"; fi

fail=0
check() { # check <file> <expected sha256>
  local got
  if [ ! -f "$1" ]; then echo "MISSING  $1" >&2; fail=1; return; fi
  got=$(sha256sum "$1" | cut -d' ' -f1)
  if [ "$got" = "$2" ]; then
    echo "ok       $1"
  else
    echo "MISMATCH $1: got $got, want $2" >&2
    fail=1
  fi
}

cd "$work"
echo "== downloading into $work"
npm pack --silent "$BUNNY" "$TEAPOT" >/dev/null
apt-get download -q "$DEB_PKG=$DEB_VER" "$CGAL_PKG=$CGAL_VER" >/dev/null
deb="${DEB_PKG}_${DEB_VER}_all.deb"
cgal_deb="${CGAL_PKG}_${CGAL_VER}_all.deb"

echo "== downloads"
check bunny-1.0.1.tgz "$SUM_BUNNY_TGZ"
check teapot-1.0.0.tgz "$SUM_TEAPOT_TGZ"
check "$deb" "$SUM_DEB"
check "$cgal_deb" "$SUM_CGAL_DEB"
[ "$fail" = 0 ] || { echo "download checksum mismatch; not going on" >&2; exit 1; }

mkdir -p bunny teapot deb cgal cgal_data out
tar -xzf bunny-1.0.1.tgz -C bunny
tar -xzf teapot-1.0.0.tgz -C teapot
dpkg-deb -x "$deb" deb
dpkg-deb -x "$cgal_deb" cgal
tar -xzf "cgal/$CGAL_TGZ" -C cgal_data "$ARMADILLO_OFF"
check "cgal_data/$ARMADILLO_OFF" "$SUM_ARMADILLO_OFF"

node "$here/npm_mesh_to_obj.js" bunny/package/index.js out/bunny.obj
node "$here/npm_mesh_to_obj.js" teapot/package/teapot.js out/teapot.obj
cp "deb/$EXR_DIR/$EXR" "out/$EXR"
python3 "$here/off_to_obj.py" "cgal_data/$ARMADILLO_OFF" out/armadillo.obj \
  --comment "$ARMADILLO_SRC" --comment "$ARMADILLO_CREDIT"

echo "== rebuilt files"
check out/bunny.obj "$SUM_BUNNY_OBJ"
check out/teapot.obj "$SUM_TEAPOT_OBJ"
check "out/$EXR" "$SUM_EXR"
check out/armadillo.obj "$SUM_ARMADILLO_OBJ"

if [ "$install" = 1 ] && [ "$fail" = 0 ]; then
  mkdir -p "$data"
  cp out/bunny.obj out/teapot.obj "out/$EXR" out/armadillo.obj "$data/"
  echo "== installed into $data"
fi

echo "== committed files"
check "$data/bunny.obj" "$SUM_BUNNY_OBJ"
check "$data/teapot.obj" "$SUM_TEAPOT_OBJ"
check "$data/$EXR" "$SUM_EXR"
check "$data/armadillo.obj" "$SUM_ARMADILLO_OBJ"

if [ "$fail" = 0 ]; then echo "all checksums match"; else echo "checksum mismatch" >&2; fi
exit "$fail"
