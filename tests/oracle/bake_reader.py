"""An independent reader of Antumbra bake files, written from docs/bake-format.md alone.

It shares no code with the library: if the document and the library disagree,
the test that runs it (tests/tests/bake_reader.rs) fails. Standard library and
numpy only.

    python bake_reader.py describe FILE
        prints the header fields, one `name value` line each; for a lightmap
        (version 3) also `atlas_width`, `atlas_height`, `texel_count` and
        `texels_crc32` (zlib.crc32 of the texel section's bytes).
    python bake_reader.py compare DENSE COMPRESSED
        reconstructs every vertex (or texel) block of the PCA-compressed file
        (version 1, 2 or 3) and prints `relative_rms_error E`, its error against
        the dense file's blocks, sqrt(sum |M - M^|^2 / sum |M|^2), then the
        compressed file's header fields. Both files must hold the same vertices
        (and, for lightmaps, the same atlas and texels).

A bad file prints `error WHAT` on standard error and exits with status 1.
"""

import struct
import sys
import zlib

import numpy as np

MAGIC = b"ANTXFER\0"
KIND_MRT = 3
HEADER_LEN = {1: 72, 2: 76, 3: 84}
MAX_ATLAS_SIDE = 16384
MAX_ATLAS_TEXELS = 1 << 26


class BadFile(Exception):
    pass


def block_len(kind, bands, grid):
    n = bands * bands
    if kind == 1:
        return n
    if kind == 2:
        return n * n
    if kind == 3:
        return grid * grid * n
    raise BadFile(f"kind {kind}")


def read(path):
    data = open(path, "rb").read()
    if len(data) < 8:
        raise BadFile("truncated")
    if data[:8] != MAGIC:
        raise BadFile("magic")
    if len(data) < 12:
        raise BadFile("truncated")
    (version,) = struct.unpack_from("<I", data, 8)
    if version not in HEADER_LEN:
        raise BadFile(f"version {version}")
    header_len = HEADER_LEN[version]
    if len(data) < header_len:
        raise BadFile("truncated header")
    (header_crc,) = struct.unpack_from("<I", data, header_len - 4)
    if zlib.crc32(data[: header_len - 4]) != header_crc:
        raise BadFile("header_crc32")
    (kind, bands, grid, components, vertices, rays, bounces) = struct.unpack_from("<7I", data, 12)
    (albedo,) = struct.unpack_from("<f", data, 40)
    (brdf_kind,) = struct.unpack_from("<I", data, 44)
    params = struct.unpack_from("<2f", data, 48)
    (payload_len,) = struct.unpack_from("<Q", data, 56)
    if version == 2:
        (clusters,) = struct.unpack_from("<I", data, 64)
        if components == 0 or not 2 <= clusters <= vertices:
            raise BadFile("clusters")
    elif version == 3:
        (clusters,) = struct.unpack_from("<I", data, 64)
        # 0 for a dense payload; 1 is a PCA with one global basis.
        allowed = clusters == 0 if components == 0 else 1 <= clusters <= vertices
        if not allowed:
            raise BadFile("clusters")
    else:
        clusters = 1 if components > 0 else 0
    lightmap = version == 3
    if lightmap:
        (width, height) = struct.unpack_from("<2I", data, 68)
        if not 1 <= width <= MAX_ATLAS_SIDE:
            raise BadFile("atlas_width")
        if not 1 <= height <= MAX_ATLAS_SIDE or width * height > MAX_ATLAS_TEXELS:
            raise BadFile("atlas_height")
    if components > 0 and kind != KIND_MRT:
        raise BadFile("components")
    d = block_len(kind, bands, grid)
    k = components
    # Positions and normals, and in a lightmap each entry's texel.
    values = (7 if lightmap else 6) * vertices
    if k == 0:
        values += vertices * d
    else:
        # Cluster indices only with two or more clusters (version 2, or 3).
        values += clusters * d * (k + 1) + vertices * k + (vertices if clusters >= 2 else 0)
    if payload_len != 4 * values:
        raise BadFile("payload_len")
    (payload_crc,) = struct.unpack_from("<I", data, header_len - 8)
    payload = data[header_len:]
    if len(payload) != payload_len:
        raise BadFile("truncated" if len(payload) < payload_len else "trailing bytes")
    if zlib.crc32(payload) != payload_crc:
        raise BadFile("payload_crc32")
    floats = np.frombuffer(payload, dtype="<f4")
    at = 0

    def take(count):
        nonlocal at
        out = floats[at : at + count]
        at += count
        return out

    def take_u32(count):
        # A section of integers: its bytes read again as u32.
        nonlocal at
        start = 4 * at
        out = np.frombuffer(payload[start : start + 4 * count], dtype="<u4")
        at += count
        return out

    out = {
        "version": version,
        "kind": kind,
        "bands": bands,
        "grid": grid,
        "components": components,
        "clusters": clusters,
        "vertex_count": vertices,
        "rays": rays,
        "bounces": bounces,
        "albedo": float(albedo),
        "brdf_kind": brdf_kind,
        "brdf_params": [float(p) for p in params],
    }
    positions = take(3 * vertices).reshape(vertices, 3)
    normals = take(3 * vertices).reshape(vertices, 3)
    # The length in single precision, as the document says.
    length = np.sqrt(np.sum(normals * normals, axis=1, dtype=np.float32), dtype=np.float32)
    if np.any(np.abs(length - np.float32(1.0)) >= np.float32(1e-3)):
        raise BadFile("normals")
    if components == 0:
        blocks = take(vertices * d).reshape(vertices, d)
    else:
        k = components
        mean = take(clusters * d).reshape(clusters, d)
        basis = take(clusters * k * d).reshape(clusters, k, d)
        weights = take(vertices * k).reshape(vertices, k)
        if clusters >= 2:
            cluster_of = take_u32(vertices)
            if np.any(cluster_of >= clusters):
                raise BadFile("clusters section")
        else:
            cluster_of = np.zeros(vertices, dtype=np.uint32)
        for name, section in (("mean", mean), ("components", basis), ("weights", weights)):
            if not np.all(np.isfinite(section)):
                raise BadFile(name)
        m = mean[cluster_of].astype(np.float64)
        b = basis[cluster_of].astype(np.float64)
        blocks = m + np.einsum("vk,vkd->vd", weights.astype(np.float64), b)
    if lightmap:
        texels_start = 4 * at
        texels = take_u32(vertices).astype(np.int64)
        # Each below W * H and above the one before it: the first that is not.
        bad = (texels >= width * height) | np.concatenate(([False], texels[1:] <= texels[:-1]))
        if np.any(bad):
            raise BadFile(f"texels[{int(np.argmax(bad))}]")
        out["atlas_width"] = width
        out["atlas_height"] = height
        out["texel_count"] = len(texels)
        out["texels_crc32"] = zlib.crc32(payload[texels_start : texels_start + 4 * vertices])
        out["texels"] = texels
    if at != len(floats):
        raise BadFile("trailing values")
    if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(normals))):
        raise BadFile("positions or normals")
    if components == 0 and not np.all(np.isfinite(blocks)):
        raise BadFile("data")
    out["positions"] = positions
    out["blocks"] = np.asarray(blocks, dtype=np.float64)
    return out


def header(f):
    return {k: v for k, v in f.items() if k not in ("positions", "blocks", "texels")}


def print_fields(fields):
    for name, value in fields.items():
        if isinstance(value, list):
            value = " ".join(repr(v) for v in value)
        print(f"{name} {value!r}" if isinstance(value, float) else f"{name} {value}")


def main(argv):
    try:
        if len(argv) == 3 and argv[1] == "describe":
            print_fields(header(read(argv[2])))
        elif len(argv) == 4 and argv[1] == "compare":
            dense, compressed = read(argv[2]), read(argv[3])
            if dense["components"] != 0 or dense["kind"] != KIND_MRT:
                raise BadFile("the first file must be a dense MRT set")
            if not np.array_equal(dense["positions"], compressed["positions"]):
                raise BadFile("the files hold different vertices")
            atlas = [(f.get("atlas_width"), f.get("atlas_height")) for f in (dense, compressed)]
            texels = [f.get("texels") for f in (dense, compressed)]
            if atlas[0] != atlas[1] or (texels[0] is None) != (texels[1] is None):
                raise BadFile("one file is a lightmap and the other is not, or of another atlas")
            if texels[0] is not None and not np.array_equal(texels[0], texels[1]):
                raise BadFile("the files hold different texels")
            a, b = dense["blocks"], compressed["blocks"]
            error = float(np.sqrt(np.sum((a - b) ** 2) / np.sum(a**2)))
            print(f"relative_rms_error {error!r}")
            print_fields(header(compressed))
        else:
            print(__doc__, file=sys.stderr)
            return 2
    except BadFile as e:
        print(f"error {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
