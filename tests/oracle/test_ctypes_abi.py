#!/usr/bin/env python3
"""The C ABI of libantumbra.so driven from Python through ctypes, exactly as a
foreign caller would, and compared with Embree (embreex) directly.

    VENV/bin/python tests/oracle/test_ctypes_abi.py [path/to/libantumbra.so]

The library defaults to $ANTUMBRA_LIB, else target/release/libantumbra.so.
Prints one line per check and 'N passed, M failed'; exits non-zero on failure.
"""

import ctypes as C
import os
import sys

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

ROOT = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", ".."))
OK, NULL_ARGUMENT, INVALID_ARGUMENT, NON_FINITE, INDEX_OUT_OF_RANGE = 0, 1, 2, 3, 4


class MeshView(C.Structure):
    _fields_ = [
        ("positions", C.POINTER(C.c_float)),
        ("vertex_count", C.c_size_t),
        ("position_stride", C.c_size_t),
        ("indices", C.POINTER(C.c_uint32)),
        ("triangle_count", C.c_size_t),
    ]


class Hit(C.Structure):
    _fields_ = [("distance", C.c_float), ("triangle", C.c_uint32), ("u", C.c_float), ("v", C.c_float)]


class SsvStatistics(C.Structure):
    _fields_ = [(name, C.c_uint32) for name in
                ("structure", "sample_count", "words_per_receiver", "light_vertex_count")] + \
               [(name, C.c_uint64) for name in
                ("edges", "potential_edges", "near_light_triangles", "nodes", "bytes", "queries",
                 "candidates", "silhouettes", "rays")] + [("candidates_per_query", C.c_double)]


def load_library(path):
    lib = C.CDLL(path)
    lib.antumbra_scene_create.argtypes = [C.POINTER(MeshView), C.POINTER(C.c_void_p)]
    lib.antumbra_scene_create.restype = C.c_int32
    fp = C.POINTER(C.c_float)
    lib.antumbra_scene_occluded.argtypes = [C.c_void_p, fp, fp, fp, C.c_size_t, C.POINTER(C.c_uint8)]
    lib.antumbra_scene_occluded.restype = C.c_int32
    lib.antumbra_scene_intersect.argtypes = [C.c_void_p, fp, fp, fp, C.c_size_t, C.POINTER(Hit)]
    lib.antumbra_scene_intersect.restype = C.c_int32
    lib.antumbra_scene_destroy.argtypes = [C.c_void_p]
    lib.antumbra_scene_destroy.restype = None
    lib.antumbra_ssv_create.argtypes = [C.POINTER(MeshView), fp, C.c_size_t, fp, C.c_size_t, C.c_void_p,
                                        C.POINTER(C.c_void_p)]
    lib.antumbra_ssv_create.restype = C.c_int32
    lib.antumbra_ssv_query.argtypes = [C.c_void_p, fp, C.c_size_t, C.POINTER(C.c_uint64), C.POINTER(C.c_uint32)]
    lib.antumbra_ssv_query.restype = C.c_int32
    lib.antumbra_ssv_get_statistics.argtypes = [C.c_void_p, C.POINTER(SsvStatistics)]
    lib.antumbra_ssv_get_statistics.restype = C.c_int32
    lib.antumbra_ssv_generate_samples.argtypes = [fp, C.c_size_t, C.c_size_t, C.c_uint32, C.c_uint64, fp]
    lib.antumbra_ssv_generate_samples.restype = C.c_int32
    lib.antumbra_ssv_destroy.argtypes = [C.c_void_p]
    lib.antumbra_ssv_destroy.restype = None
    lib.antumbra_last_error_message.restype = C.c_char_p
    lib.antumbra_version.restype = C.c_uint32
    return lib


def load_obj(path):
    verts, tris = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                tris.append([int(p.split("/")[0]) - 1 for p in parts[1:4]])
    return np.array(verts, np.float32), np.array(tris, np.uint32)


def ptr(array, ctype):
    return array.ctypes.data_as(C.POINTER(ctype))


def ao_rays(rng, verts, tris, count):
    """Rays from points on random triangles, offset along the normal, into the
    upper hemisphere, with finite lengths: the queries ambient occlusion makes."""
    t = rng.integers(0, len(tris), count)
    a, b, c = (verts[tris[t, k]].astype(np.float64) for k in range(3))
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    p = a + (b - a) * u[:, None] + (c - a) * v[:, None]
    n = np.cross(b - a, c - a)
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-30)[:, None]
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    d *= np.sign(np.einsum("ij,ij->i", d, n))[:, None]
    radius = float(np.linalg.norm(verts.max(0) - verts.min(0))) / 2
    origins = (p + n * radius * 1e-3).astype(np.float32)
    t_max = (radius * rng.uniform(0.05, 2.0, count)).astype(np.float32)
    return origins, np.ascontiguousarray(d, np.float32), t_max


def check_ssv(lib, checks, verts, tris):
    """Soft shadows of the bunny on a plane below it from a square light above it:
    every bit against an Embree occlusion ray over the same segment."""
    lo, hi = verts.min(0).astype(np.float64), verts.max(0).astype(np.float64)
    size = float(np.max(hi - lo))
    centre = (lo + hi) / 2
    # y is up: the light 0.6 size above the top, half a size wide; receivers on a
    # plane 0.05 size below the bottom, over twice the footprint.
    half = 0.25 * size
    light = np.array([[centre[0] + dx * half, hi[1] + 0.6 * size, centre[2] + dz * half]
                      for dx, dz in ((-1, -1), (-1, 1), (1, 1), (1, -1))], np.float32)
    n_samples = 64
    samples = np.full((n_samples, 3), 7.0, np.float32)
    r = lib.antumbra_ssv_generate_samples(ptr(light, C.c_float), 4, n_samples, 0, 11, ptr(samples, C.c_float))
    checks.check("ssv_generate_samples", r == OK and np.all(np.abs(samples[:, 1] - light[0, 1]) < 1e-4 * size))
    view = MeshView(ptr(verts, C.c_float), len(verts), 0, ptr(tris, C.c_uint32), len(tris))
    ssv = C.c_void_p()
    r = lib.antumbra_ssv_create(C.byref(view), ptr(light, C.c_float), 4, ptr(samples, C.c_float), n_samples,
                                None, C.byref(ssv))
    checks.check("ssv_create", r == OK, lib.antumbra_last_error_message().decode())
    if r != OK:
        return
    side = 40
    xs = np.linspace(lo[0] - 0.5 * (hi[0] - lo[0]), hi[0] + 0.5 * (hi[0] - lo[0]), side)
    zs = np.linspace(lo[2] - 0.5 * (hi[2] - lo[2]), hi[2] + 0.5 * (hi[2] - lo[2]), side)
    gx, gz = np.meshgrid(xs, zs)
    points = np.stack([gx.ravel(), np.full(gx.size, lo[1] - 0.05 * size), gz.ravel()], 1).astype(np.float32)
    count = len(points)
    bits = np.full(count, 0xA5A5A5A5A5A5A5A5, np.uint64)
    visible = np.zeros(count, np.uint32)
    r = lib.antumbra_ssv_query(ssv, ptr(points, C.c_float), count, ptr(bits, C.c_uint64), ptr(visible, C.c_uint32))
    checks.check("ssv_query", r == OK, lib.antumbra_last_error_message().decode())
    ours = ((bits[:, None] >> np.arange(n_samples, dtype=np.uint64)[None, :]) & np.uint64(1)).astype(bool)
    checks.check("ssv visible_counts are the bits set", (ours.sum(1) == visible).all())
    # Embree: one ray per (receiver, sample), origin the receiver, direction the
    # segment, t in (0, 1) (the light is not in the scene, so the end is free).
    origins = np.repeat(points, n_samples, 0)
    dirs = (np.tile(samples, (count, 1)).astype(np.float64) - origins).astype(np.float32)
    embree = rtcore_scene.EmbreeScene(robust=True)
    TriangleMesh(embree, verts, tris.astype(np.int32))
    emb_visible = (embree.run(origins, dirs, dists=np.ones(len(origins), np.float32), query="OCCLUDED") != 0)
    emb_visible = emb_visible.reshape(count, n_samples)
    mismatches = int(np.sum(ours != emb_visible))
    shadowed = float(np.mean(~ours))
    checks.check("ssv bits agree with Embree occlusion rays (<= 1e-4 of bits)",
                 mismatches <= 1e-4 * ours.size and 0.02 < shadowed < 0.9,
                 f"{mismatches} of {ours.size} bits differ; {100 * shadowed:.1f} % of bits shadowed")
    stats = SsvStatistics()
    r = lib.antumbra_ssv_get_statistics(ssv, C.byref(stats))
    checks.check("ssv_get_statistics", r == OK and stats.queries == count and stats.sample_count == n_samples
                 and stats.words_per_receiver == 1 and stats.nodes > 0,
                 f"{stats.candidates_per_query:.1f} candidates per query of {stats.potential_edges} edges, "
                 f"{stats.nodes} nodes")
    nan_points = points[:3].copy()
    nan_points[1, 2] = np.nan
    out = np.full(3, 5, np.uint64)
    r = lib.antumbra_ssv_query(ssv, ptr(nan_points, C.c_float), 3, ptr(out, C.c_uint64), None)
    msg = lib.antumbra_last_error_message().decode()
    checks.check("ssv NaN point", r == NON_FINITE and "points[1]" in msg and (out == 5).all(), msg)
    lib.antumbra_ssv_destroy(ssv)
    lib.antumbra_ssv_destroy(None)


class Checks:
    def __init__(self):
        self.passed = self.failed = 0

    def check(self, name, ok, detail=""):
        print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail else ''}")
        if ok:
            self.passed += 1
        else:
            self.failed += 1


def main():
    lib_path = sys.argv[1] if len(sys.argv) > 1 else os.environ.get(
        "ANTUMBRA_LIB", os.path.join(ROOT, "target", "release", "libantumbra.so"))
    if not os.path.exists(lib_path):
        print(f"{lib_path} does not exist: build it with `cargo build --release -p antumbra-ffi`")
        print("0 passed, 1 failed")
        return 1
    lib = load_library(lib_path)
    checks = Checks()
    verts, tris = load_obj(os.path.join(ROOT, "tests", "data", "bunny.obj"))
    checks.check("bunny loaded", (len(verts), len(tris)) == (1839, 3674))

    view = MeshView(ptr(verts, C.c_float), len(verts), 0, ptr(tris, C.c_uint32), len(tris))
    scene = C.c_void_p()
    checks.check("scene_create", lib.antumbra_scene_create(C.byref(view), C.byref(scene)) == OK)

    rng = np.random.default_rng(2024)
    count = 100_000
    origins, dirs, t_max = ao_rays(rng, verts, tris, count)
    occluded = np.full(count, 7, np.uint8)
    r = lib.antumbra_scene_occluded(scene, ptr(origins, C.c_float), ptr(dirs, C.c_float),
                                    ptr(t_max, C.c_float), count, ptr(occluded, C.c_uint8))
    checks.check("scene_occluded", r == OK and set(np.unique(occluded)) <= {0, 1})
    hits = (Hit * count)()
    r = lib.antumbra_scene_intersect(scene, ptr(origins, C.c_float), ptr(dirs, C.c_float),
                                     ptr(t_max, C.c_float), count, hits)
    ours_t = np.frombuffer(hits, dtype=np.dtype([("t", "<f4"), ("tri", "<u4"), ("u", "<f4"), ("v", "<f4")]))["t"]
    checks.check("scene_intersect", r == OK)

    embree = rtcore_scene.EmbreeScene(robust=True)
    TriangleMesh(embree, verts, tris.astype(np.int32))
    emb_occ = embree.run(origins, dirs, dists=t_max.copy(), query="OCCLUDED") == 0
    res = embree.run(origins, dirs, dists=t_max.copy(), query="INTERSECT", output=1)
    emb_hit = res["primID"] != -1
    emb_t = np.where(emb_hit, res["tfar"], np.inf)

    agree = float(np.mean((occluded == 1) == emb_occ))
    checks.check("occlusion agrees with Embree on 100,000 AO rays", agree >= 0.9999,
                 f"{100 * agree:.4f} % ({int(np.sum(occluded == 1))} occluded)")
    both = emb_hit & np.isfinite(ours_t)
    rel = np.abs(ours_t[both] - emb_t[both]) / emb_t[both]
    close = float(np.mean(rel <= 1e-4)) if both.any() else 0.0
    checks.check("closest-hit distances within 1e-4 relative", close >= 0.9999 and both.sum() > count // 20,
                 f"{100 * close:.4f} % of {int(both.sum())} common hits")

    # Failure paths exactly as a foreign caller meets them.
    sentinel = C.c_void_p(0x5A5A)
    r = lib.antumbra_scene_create(None, C.byref(sentinel))
    msg = lib.antumbra_last_error_message().decode()
    checks.check("NULL mesh", r == NULL_ARGUMENT and "mesh" in msg and sentinel.value == 0x5A5A, msg)
    bad = tris.copy()
    bad[10, 2] = len(verts)
    bad_view = MeshView(ptr(verts, C.c_float), len(verts), 0, ptr(bad, C.c_uint32), len(bad))
    r = lib.antumbra_scene_create(C.byref(bad_view), C.byref(sentinel))
    msg = lib.antumbra_last_error_message().decode()
    checks.check("index out of range", r == INDEX_OUT_OF_RANGE and "mesh->indices[32]" in msg, msg)
    nan_origins = origins[:4].copy()
    nan_origins[2, 1] = np.nan
    out = np.full(4, 9, np.uint8)
    r = lib.antumbra_scene_occluded(scene, ptr(nan_origins, C.c_float), ptr(dirs, C.c_float),
                                    ptr(t_max, C.c_float), 4, ptr(out, C.c_uint8))
    msg = lib.antumbra_last_error_message().decode()
    checks.check("NaN origin", r == NON_FINITE and "origins[2]" in msg and (out == 9).all(), msg)
    check_ssv(lib, checks, verts, tris)
    v = lib.antumbra_version()
    checks.check("version", v >> 16 == 0 and v > 0, hex(v))

    lib.antumbra_scene_destroy(scene)
    lib.antumbra_scene_destroy(None)
    print(f"{checks.passed} passed, {checks.failed} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
