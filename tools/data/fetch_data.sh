#!/usr/bin/env bash
# Reproduce the third-party test data in tests/data/ from scratch, in a temp dir,
# and check it byte for byte against pinned sha256 sums. See tests/data/SOURCES.md.
#
# Usage: tools/data/fetch_data.sh            # rebuild in a temp dir, verify, then delete it
#        KEEP=1 tools/data/fetch_data.sh     # keep the temp dir (path is printed)
#        tools/data/fetch_data.sh --install  # also copy the rebuilt files into tests/data/
#
# Needs: node + npm (npm registry), apt-get + dpkg-deb (Debian bookworm archive;
# run `apt-get update` once first), sha256sum.
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

# sha256 of the downloads.
SUM_BUNNY_TGZ=381e02c74b98cf18814d7bec794726ef70b9c67e037273e82054d0043f6ae303
SUM_TEAPOT_TGZ=ebe7143533ff1a35ea25738b43112d36fd9ae072652bde9b2144057e7218890f
SUM_DEB=5ceaf56a49ba3ded95c751d739aeec3d19e7fad76fba5cb70666986af9303b0e
# sha256 of the committed files in tests/data/.
SUM_BUNNY_OBJ=5d2d52d32a03db4a568d87f3dfb4010c30a7945c4b56e079c8a25aae94d94d40
SUM_TEAPOT_OBJ=4bdd18062aa64d278d505635e8e6b2a68f77873f31596bc24ba0280ba9834d9c
SUM_EXR=b97206217e29763d62d9a65ad2d7058460acfb4824659e7a59f5bde374f21937

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
apt-get download -q "$DEB_PKG=$DEB_VER" >/dev/null
deb="${DEB_PKG}_${DEB_VER}_all.deb"

echo "== downloads"
check bunny-1.0.1.tgz "$SUM_BUNNY_TGZ"
check teapot-1.0.0.tgz "$SUM_TEAPOT_TGZ"
check "$deb" "$SUM_DEB"
[ "$fail" = 0 ] || { echo "download checksum mismatch; not going on" >&2; exit 1; }

mkdir -p bunny teapot deb out
tar -xzf bunny-1.0.1.tgz -C bunny
tar -xzf teapot-1.0.0.tgz -C teapot
dpkg-deb -x "$deb" deb

node "$here/npm_mesh_to_obj.js" bunny/package/index.js out/bunny.obj
node "$here/npm_mesh_to_obj.js" teapot/package/teapot.js out/teapot.obj
cp "deb/$EXR_DIR/$EXR" "out/$EXR"

echo "== rebuilt files"
check out/bunny.obj "$SUM_BUNNY_OBJ"
check out/teapot.obj "$SUM_TEAPOT_OBJ"
check "out/$EXR" "$SUM_EXR"

if [ "$install" = 1 ] && [ "$fail" = 0 ]; then
  mkdir -p "$data"
  cp out/bunny.obj out/teapot.obj "out/$EXR" "$data/"
  echo "== installed into $data"
fi

echo "== committed files"
check "$data/bunny.obj" "$SUM_BUNNY_OBJ"
check "$data/teapot.obj" "$SUM_TEAPOT_OBJ"
check "$data/$EXR" "$SUM_EXR"

if [ "$fail" = 0 ]; then echo "all checksums match"; else echo "checksum mismatch" >&2; fi
exit "$fail"
