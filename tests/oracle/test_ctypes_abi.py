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
BUFFER_TOO_SMALL, INVALID_DATA = 5, 10
TRANSFER_KIND_DIFFUSE = 1


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


class TransferOptions(C.Structure):
    _fields_ = [
        ("kind", C.c_uint32), ("bands", C.c_uint32), ("grid", C.c_uint32), ("rays", C.c_uint32),
        ("bounces", C.c_uint32), ("parallel", C.c_uint32), ("brdf", C.c_uint32),
        ("brdf_params", C.c_float * 2), ("albedo", C.c_float), ("ray_offset", C.c_float),
        ("reserved", C.c_uint32), ("seed", C.c_uint64),
    ]


class TransferMaterial(C.Structure):
    _fields_ = [
        ("albedo", C.c_float * 3), ("specular", C.c_float * 3), ("phong_exponent", C.c_float),
        ("eye", C.c_float * 3), ("view_directions", C.POINTER(C.c_float)),
    ]


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
    vp, sz, u8p = C.c_void_p, C.c_size_t, C.POINTER(C.c_uint8)
    lib.antumbra_transfer_options_init.argtypes = [C.POINTER(TransferOptions)]
    lib.antumbra_transfer_options_init.restype = None
    lib.antumbra_transfer_material_init.argtypes = [C.POINTER(TransferMaterial)]
    lib.antumbra_transfer_material_init.restype = None
    lib.antumbra_transfer_bake.argtypes = [C.POINTER(MeshView), fp, C.POINTER(TransferOptions), vp, vp,
                                           C.POINTER(C.c_void_p)]
    lib.antumbra_transfer_bake.restype = C.c_int32
    lib.antumbra_transfer_geometry.argtypes = [vp, fp, fp, sz]
    lib.antumbra_transfer_geometry.restype = C.c_int32
    lib.antumbra_transfer_shade.argtypes = [vp, fp, sz, C.POINTER(TransferMaterial), C.c_uint32, fp, sz]
    lib.antumbra_transfer_shade.restype = C.c_int32
    lib.antumbra_transfer_save.argtypes = [vp, u8p, sz, C.POINTER(C.c_size_t)]
    lib.antumbra_transfer_save.restype = C.c_int32
    lib.antumbra_transfer_load.argtypes = [u8p, sz, C.POINTER(C.c_void_p)]
    lib.antumbra_transfer_load.restype = C.c_int32
    lib.antumbra_transfer_destroy.argtypes = [vp]
    lib.antumbra_transfer_destroy.restype = None
    lib.antumbra_sh_eval.argtypes = [fp, C.c_uint32, fp]
    lib.antumbra_sh_eval.restype = C.c_int32
    return lib


def sh9(d):
    """Real SH, 3 bands, Condon-Shortley phase (the library's convention), per row of d."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack([
        np.full_like(x, 0.282095), -0.488603 * y, 0.488603 * z, -0.488603 * x,
        1.092548 * x * y, -1.092548 * y * z, 0.315392 * (3 * z * z - 1), -1.092548 * x * z,
        0.546274 * (x * x - y * y)], axis=1)


def bake_diffuse(lib, checks, view, options, n):
    """Bakes through the ABI; returns the handle and the transfer vectors, read one
    coefficient at a time: unit red lighting e_j and a diffuse albedo of pi make
    the shaded red channel t_j."""
    handle = C.c_void_p()
    r = lib.antumbra_transfer_bake(C.byref(view), None, C.byref(options), None, None, C.byref(handle))
    checks.check(f"transfer_bake (bunny, diffuse, 3 bands, {options.rays} rays, seed {options.seed})", r == OK,
                 lib.antumbra_last_error_message().decode())
    if r != OK:
        return None, None
    material = TransferMaterial()
    lib.antumbra_transfer_material_init(C.byref(material))
    material.albedo[0] = np.pi
    vectors = np.zeros((n, 9))
    rgb = np.zeros((n, 3), np.float32)
    for j in range(9):
        lighting = np.zeros(27, np.float32)
        lighting[j] = 1.0
        r = lib.antumbra_transfer_shade(handle, ptr(lighting, C.c_float), 27, C.byref(material), 0,
                                        ptr(rgb, C.c_float), n)
        if r != OK:
            checks.check("transfer_shade", False, lib.antumbra_last_error_message().decode())
            lib.antumbra_transfer_destroy(handle)
            return None, None
        vectors[:, j] = rgb[:, 0]
    return handle, vectors


def check_transfer(lib, checks, verts, tris, embree):
    """Diffuse transfer (0 bounces) baked through the C ABI against a Monte Carlo
    reference whose visibility Embree traces: t_j = ∫_H V(ω) Y_j(ω) cos θ dω."""
    view = MeshView(ptr(verts, C.c_float), len(verts), 0, ptr(tris, C.c_uint32), len(tris))
    radius = float(np.linalg.norm(verts.max(0) - verts.min(0))) / 2
    options = TransferOptions()
    lib.antumbra_transfer_options_init(C.byref(options))
    options.kind, options.bands, options.rays = TRANSFER_KIND_DIFFUSE, 3, 1024
    options.ray_offset = radius * 1e-4
    handle, ours = bake_diffuse(lib, checks, view, options, len(verts))
    if handle is None:
        return
    n = len(verts)
    positions, normals = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32)
    r = lib.antumbra_transfer_geometry(handle, ptr(positions, C.c_float), ptr(normals, C.c_float), n)
    checks.check("transfer_geometry", r == OK and np.array_equal(positions, verts))
    # A second seed measures our own Monte Carlo noise: Var(a - b) = 2 Var(a).
    options.seed = 1
    other, ours_b = bake_diffuse(lib, checks, view, options, n)
    if other is None:
        return
    lib.antumbra_transfer_destroy(other)

    # Our SH polynomials agree with the library's.
    d = np.array([[0.36, 0.48, 0.8], [0.0, -0.6, 0.8], [-1.0, 0.0, 0.0]], np.float32)
    values = np.zeros(9, np.float32)
    same = True
    for row in d:
        row = np.ascontiguousarray(row)
        same &= lib.antumbra_sh_eval(ptr(row, C.c_float), 3, ptr(values, C.c_float)) == OK
        same &= bool(np.allclose(values, sh9(row[None, :])[0], atol=1e-5))
    checks.check("reference SH polynomials match antumbra_sh_eval", same)

    # Reference: M cosine-weighted directions per vertex, visibility from Embree.
    rng = np.random.default_rng(5)
    picked = rng.choice(n, 48, replace=False)
    samples = 16384
    err = norm = variance = ours_variance = 0.0
    for v in picked:
        nrm = normals[v].astype(np.float64)
        helper = np.array([1.0, 0, 0]) if abs(nrm[0]) < 0.9 else np.array([0, 1.0, 0])
        t = np.cross(nrm, helper)
        t /= np.linalg.norm(t)
        b = np.cross(nrm, t)
        u1, u2 = rng.random(samples), rng.random(samples)
        rr, phi = np.sqrt(u1), 2 * np.pi * u2
        local = np.stack([rr * np.cos(phi), rr * np.sin(phi), np.sqrt(1 - u1)], axis=1)
        dirs = local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * nrm
        origins = np.tile(positions[v] + nrm * options.ray_offset, (samples, 1)).astype(np.float32)
        dirs32 = np.ascontiguousarray(dirs, np.float32)
        far = np.full(samples, np.inf, np.float32)
        visible = embree.run(origins, dirs32, dists=far, query="OCCLUDED") != 0
        terms = np.pi * visible[:, None] * sh9(dirs)
        ref = terms.mean(axis=0)
        variance += float(np.sum(terms.var(axis=0))) / samples
        ours_variance += float(np.sum((ours[v] - ours_b[v]) ** 2)) / 2
        err += float(np.sum((ours[v] - ref) ** 2))
        norm += float(np.sum(ref ** 2))
    rel = np.sqrt(err / norm)
    # Both sides are Monte Carlo: three standard errors, from the reference's
    # measured sample variance and our noise measured across two seeds.
    bound = 3 * np.sqrt((variance + ours_variance) / norm)
    checks.check("diffuse transfer vs Embree-traced reference (48 vertices)", rel < bound,
                 f"relative RMS {100 * rel:.2f} % (bound {100 * bound:.2f} %: reference noise "
                 f"{100 * np.sqrt(variance / norm):.2f} %, ours {100 * np.sqrt(ours_variance / norm):.2f} %)")

    # A truncated bake file is refused with INVALID_DATA and the handle untouched.
    size = C.c_size_t()
    r = lib.antumbra_transfer_save(handle, None, 0, C.byref(size))
    data = np.zeros(size.value, np.uint8)
    r2 = lib.antumbra_transfer_save(handle, ptr(data, C.c_uint8), size.value, None)
    out = C.c_void_p(0x5A5A)
    r3 = lib.antumbra_transfer_load(ptr(data, C.c_uint8), size.value - 1, C.byref(out))
    msg = lib.antumbra_last_error_message().decode()
    checks.check("truncated bake file", r == BUFFER_TOO_SMALL and r2 == OK and r3 == INVALID_DATA
                 and out.value == 0x5A5A and "truncated" in msg, msg)
    r = lib.antumbra_transfer_load(ptr(data, C.c_uint8), size.value, C.byref(out))
    checks.check("bake file reloads", r == OK)
    lib.antumbra_transfer_destroy(out)
    lib.antumbra_transfer_destroy(handle)


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
    check_transfer(lib, checks, verts, tris, embree)
    v = lib.antumbra_version()
    checks.check("version", v >> 16 == 0 and v > 0, hex(v))

    lib.antumbra_scene_destroy(scene)
    lib.antumbra_scene_destroy(None)
    print(f"{checks.passed} passed, {checks.failed} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
