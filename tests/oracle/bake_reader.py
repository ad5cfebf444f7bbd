"""An independent reader of Antumbra bake files, written from docs/bake-format.md alone.

It shares no code with the library: if the document and the library disagree,
the test that runs it (tests/tests/bake_reader.rs) fails. Standard library and
numpy only.

    python bake_reader.py describe FILE
        prints the header fields, one `name value` line each.
    python bake_reader.py compare DENSE COMPRESSED
        reconstructs every vertex block of the PCA-compressed file (version 1 or
        2) and prints `relative_rms_error E`, its error against the dense file's
        blocks, sqrt(sum |M - M^|^2 / sum |M|^2), then the compressed file's
        header fields.

A bad file prints `error WHAT` on standard error and exits with status 1.
"""

import struct
import sys
import zlib

import numpy as np

MAGIC = b"ANTXFER\0"
KIND_MRT = 3


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
    if version not in (1, 2):
        raise BadFile(f"version {version}")
    header_len = 72 if version == 1 else 76
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
    else:
        clusters = 1 if components > 0 else 0
    if components > 0 and kind != KIND_MRT:
        raise BadFile("components")
    d = block_len(kind, bands, grid)
    k = components
    if k == 0:
        values = 6 * vertices + vertices * d
    else:
        values = 6 * vertices + clusters * d * (k + 1) + vertices * k + (vertices if version == 2 else 0)
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
        if version == 2:
            # The last section holds integers: read its bytes again as u32.
            start = 4 * at
            cluster_of = np.frombuffer(payload[start : start + 4 * vertices], dtype="<u4")
            at += vertices
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
    return {k: v for k, v in f.items() if k not in ("positions", "blocks")}


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
