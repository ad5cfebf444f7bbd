#!/usr/bin/env python3
"""Embree test oracle: cast rays against a triangle mesh with Embree (via embreex).

    python embree_oracle.py MESH RAYS OUT [--crossings] [--raw] [--crossing-eps EPS]

File formats (all little-endian) are described in README.md next to this file.
Exit status: 0 ok, 2 bad input (bad magic/version, truncated or oversized file,
index out of range, non-finite data) or bad usage, 1 anything else (e.g. embreex
not installed: run tests/oracle/setup_venv.sh).

How embreex 4.4.0.post1 is driven (checked against the installed package):
  * ``EmbreeScene.run(origins, directions, dists, query, output)`` requires
    float32 2-D origins/directions and a float32 1-D ``dists`` (anything else is
    a "Buffer dtype mismatch" ValueError; there is no silent conversion). It
    copies them verbatim into RTCRayHit: directions are NOT normalised, so t is
    in units of |direction|; ``tnear`` is hard-wired to 0.0 and ``tfar`` is
    ``dists[i]`` (1e37 when dists is None).
  * INTERSECT/DISTANCE write the resulting tfar back INTO the ``dists`` array
    (in place; the returned dict's 'tfar' is that same array). A miss leaves
    tfar unchanged (= the input t_max, not inf) and primID = geomID = -1.
    We therefore always pass a fresh copy and map misses to +inf ourselves.
  * OCCLUDED returns int32 0 when occluded, -1 when not (it tests the
    occluded ray's tfar < 0); it does not touch ``dists``.
  * Embree's accepted hit interval is the CLOSED [tnear, tfar] = [0, t_max]:
    a triangle at exactly t == t_max is hit/occludes, and a ray whose origin
    lies on a triangle may get a t = 0 (or -0) hit (robust scenes do;
    non-robust scenes are inconsistent about it).

The oracle's contract is the OPEN interval 0 < t < t_max, so unless --raw is
given two boundary corrections are applied on top of Embree's answers:
  * closest hit with t >= t_max  -> reported as a miss (exact: nothing is closer);
  * closest hit with t <= 0      -> re-cast starting just past it (see EPSILON
    below) and report the first hit found with t > 0;
  * occluded is Embree's occlusion answer, except that it is cleared when the
    corrected closest-hit query finds nothing in (0, t_max) (i.e. the only
    occluders sit exactly at t = 0 or t = t_max).
The scene is built with Embree's ROBUST flag (watertight: no leaks through
shared edges/vertices).

Crossings (--crossings) and EPSILON: starting from the corrected closest hit
(also under --raw),
the ray is re-cast from parameter s = t_hit + delta, where
    delta = eps * S / |d|,   S = max(max |vertex coordinate|, max |origin_i|)
(world-space step eps*S along the ray, eps = 1e-5 by default, i.e. ~100 float32
ulps at the scene's scale). The new origin o + s*d is formed in float64 and
rounded to float32, tfar = t_max - s (rounded up by Embree's closed interval
anyway), and a hit on triangle k counts if its t on the ORIGINAL ray,
recomputed in float64 from k's plane (t = n.(v0 - o) / n.d), is < t_max. This repeats until a cast misses. Consequently hits
whose t values lie within delta of each other (a ray through a shared edge or
vertex of one surface, duplicated coincident triangles) count as ONE crossing,
and surfaces closer than ~eps*S along the ray are merged; tests should keep
distinct surfaces much farther apart than that.
"""
import argparse
import os
import struct
import sys

try:
    import numpy as np
except ImportError as _e:  # not running inside the oracle venv
    sys.stderr.write(f"embree_oracle: error: cannot import numpy ({_e}); run "
                     f"tests/oracle/setup_venv.sh and use its python (target/pyenv/bin/python)\n")
    sys.exit(1)

MESH_MAGIC = b"ANTM"
RAYS_MAGIC = b"ANTR"
OUT_MAGIC = b"ANTO"
VERSION = 1
NO_HIT = 0xFFFFFFFF
FLAG_CROSSINGS = 1
FLAG_RAW = 2
DEFAULT_EPS = 1e-5

RESULT_DTYPE = np.dtype([
    ("occluded", "<u4"),
    ("t", "<f4"),
    ("prim", "<u4"),
    ("u", "<f4"),
    ("v", "<f4"),
    ("crossings", "<u4"),
])
assert RESULT_DTYPE.itemsize == 24


class InputError(Exception):
    pass


def _read_header(path, magic, what):
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise InputError(f"cannot read {what} file {path}: {e.strerror}")
    if len(data) < 16:
        raise InputError(f"{what} file {path}: truncated header ({len(data)} bytes, need 16)")
    if data[:4] != magic:
        raise InputError(f"{what} file {path}: bad magic {data[:4]!r}, expected {magic!r}")
    version, a, b = struct.unpack_from("<III", data, 4)
    if version != VERSION:
        raise InputError(f"{what} file {path}: unsupported version {version}, expected {VERSION}")
    return data, a, b


def _check_size(path, what, data, expected):
    if len(data) < expected:
        raise InputError(f"{what} file {path}: truncated: {len(data)} bytes, header says {expected}")
    if len(data) > expected:
        raise InputError(f"{what} file {path}: {len(data) - expected} unexpected trailing bytes "
                         f"({len(data)} bytes, header says {expected})")


def read_mesh(path):
    data, nv, nt = _read_header(path, MESH_MAGIC, "mesh")
    _check_size(path, "mesh", data, 16 + 12 * nv + 12 * nt)
    verts = np.frombuffer(data, dtype="<f4", count=3 * nv, offset=16).reshape(nv, 3)
    tris = np.frombuffer(data, dtype="<u4", count=3 * nt, offset=16 + 12 * nv).reshape(nt, 3)
    if nv and not np.isfinite(verts).all():
        bad = int(np.argmax(~np.isfinite(verts).all(axis=1)))
        raise InputError(f"mesh file {path}: vertex {bad} is not finite: {verts[bad].tolist()}")
    if nt and int(tris.max()) >= nv:
        bad = int(np.argmax((tris >= nv).any(axis=1)))
        raise InputError(f"mesh file {path}: triangle {bad} has index out of range "
                         f"{tris[bad].tolist()} (vertex_count = {nv})")
    return (np.ascontiguousarray(verts, dtype=np.float32),
            np.ascontiguousarray(tris, dtype=np.uint32))


def read_rays(path):
    data, n, reserved = _read_header(path, RAYS_MAGIC, "ray")
    if reserved != 0:
        raise InputError(f"ray file {path}: reserved header field is {reserved}, expected 0")
    _check_size(path, "ray", data, 16 + 28 * n)
    rays = np.frombuffer(data, dtype="<f4", count=7 * n, offset=16).reshape(n, 7)
    od = rays[:, :6]
    if n and not np.isfinite(od).all():
        bad = int(np.argmax(~np.isfinite(od).all(axis=1)))
        raise InputError(f"ray file {path}: ray {bad} has a non-finite origin/direction")
    if n and np.isnan(rays[:, 6]).any():
        bad = int(np.argmax(np.isnan(rays[:, 6])))
        raise InputError(f"ray file {path}: ray {bad} has t_max = NaN")
    orig = np.ascontiguousarray(rays[:, 0:3], dtype=np.float32)
    dirs = np.ascontiguousarray(rays[:, 3:6], dtype=np.float32)
    tmax = np.ascontiguousarray(rays[:, 6], dtype=np.float32)
    return orig, dirs, tmax


class Caster:
    def __init__(self, verts, tris, orig, dirs, tmax, eps):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        self.scene = rtcore_scene.EmbreeScene(robust=True)
        if len(verts) and len(tris):
            # Keep a reference: the mesh object owns nothing we need, but be safe.
            self.mesh = TriangleMesh(self.scene, verts, tris)
        self.orig, self.dirs, self.tmax = orig, dirs, tmax
        v64 = verts.astype(np.float64)
        t64 = tris.astype(np.int64)
        if len(t64):
            self.v0 = v64[t64[:, 0]]
            self.normals = np.cross(v64[t64[:, 1]] - self.v0, v64[t64[:, 2]] - self.v0)
        self.o64 = orig.astype(np.float64)
        self.d64 = dirs.astype(np.float64)
        self.tmax64 = tmax.astype(np.float64)
        dlen = np.linalg.norm(self.d64, axis=1)
        self.nonzero_dir = dlen > 0
        scale = float(np.abs(verts).max()) if len(verts) else 0.0
        s = np.maximum(scale, np.abs(self.o64).max(axis=1) if len(orig) else 0.0)
        s = np.maximum(s, np.finfo(np.float32).tiny)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.delta = np.where(dlen > 0, eps * s / dlen, np.inf)

    def _run(self, origins, dirs, tfar, query):
        # embreex wants float32, 2-D / 1-D, and overwrites dists in place.
        origins = np.ascontiguousarray(origins, dtype=np.float32)
        dirs = np.ascontiguousarray(dirs, dtype=np.float32)
        tfar = np.array(tfar, dtype=np.float32, copy=True, order="C")
        if query == "OCCLUDED":
            return self.scene.run(origins, dirs, dists=tfar, query="OCCLUDED")
        return self.scene.run(origins, dirs, dists=tfar, query="INTERSECT", output=1)

    def occluded(self):
        if len(self.orig) == 0:
            return np.zeros(0, bool)
        occ = self._run(self.orig, self.dirs, self.tmax, "OCCLUDED") == 0
        return occ & self.nonzero_dir

    def cast(self, idx, s):
        """Closest hit for rays idx starting at parameter s (float64, >= 0).

        Returns (hit, t_abs float64, prim, u, v). s == 0 casts the original ray
        bit-for-bit; otherwise the origin is o + s*d rounded to float32 and
        tfar = t_max - s.
        """
        if len(idx) == 0:
            z = np.zeros(0)
            return z.astype(bool), z, z.astype(np.int32), z.astype(np.float32), z.astype(np.float32)
        shifted = s != 0
        org = self.orig[idx].copy()
        tfar = self.tmax[idx].copy()
        if shifted.any():
            sh = idx[shifted]
            org[shifted] = (self.o64[sh] + s[shifted, None] * self.d64[sh]).astype(np.float32)
            # Round tfar up: the exact t_max test happens on the recomputed t below.
            tfar[shifted] = np.nextafter((self.tmax64[sh] - s[shifted]).astype(np.float32),
                                         np.float32(np.inf))
        r = self._run(org, self.dirs[idx], tfar, "INTERSECT")
        # A zero direction is a point, not a segment: never a hit.
        hit = (r["primID"] != -1) & self.nonzero_dir[idx]
        t_abs = np.where(hit, s + r["tfar"].astype(np.float64), np.inf)
        # For shifted casts the float32 origin o + s*d is rounded, so s + t' is
        # only approximately the original ray's t. Recompute t on the ORIGINAL
        # ray from the hit triangle's plane in float64, so that comparisons
        # with t_max (and t > 0) are as exact as the inputs allow.
        sel = np.nonzero(shifted & hit)[0]
        if len(sel):
            rid = idx[sel]
            prim = r["primID"][sel].astype(np.int64)
            n = self.normals[prim]
            denom = np.einsum("ij,ij->i", n, self.d64[rid])
            num = np.einsum("ij,ij->i", n, self.v0[prim] - self.o64[rid])
            good = denom != 0
            with np.errstate(divide="ignore", invalid="ignore"):
                tp = num / denom
            t_abs[sel[good]] = tp[good]
        return hit, t_abs, r["primID"], r["u"], r["v"]

    def closest(self, raw):
        n = len(self.orig)
        idx = np.arange(n)
        hit, t, prim, u, v = self.cast(idx, np.zeros(n))
        t, prim, u, v = t.copy(), prim.copy(), u.copy(), v.copy()
        if raw:
            return hit, t, prim, u, v
        # Hits at t <= 0 (origin on a surface): step past them and cast again.
        # Each iteration strictly increases s (delta > 0), so this terminates.
        for _ in range(n and 64):
            bad = np.nonzero(hit & (t <= 0))[0]
            if len(bad) == 0:
                break
            s = np.maximum(t[bad], 0.0) + self.delta[bad]
            h2, t2, p2, u2, v2 = self.cast(bad, s)
            hit[bad], t[bad], prim[bad], u[bad], v[bad] = h2, t2, p2, u2, v2
        else:
            if n and (hit & (t <= 0)).any():
                raise RuntimeError("could not step past t <= 0 hits")
        # Embree's interval is closed at t_max; ours is open.
        at_end = hit & (t >= self.tmax64)
        hit[at_end] = False
        t[~hit] = np.inf
        return hit, t, prim, u, v

    def crossings(self, hit, t, max_iter):
        count = hit.astype(np.int64)
        active = np.nonzero(hit)[0]
        last = t.copy()
        for _ in range(max_iter):
            if len(active) == 0:
                return count
            s = last[active] + self.delta[active]
            keep = s < self.tmax64[active]
            active, s = active[keep], s[keep]
            h, ta, _, _, _ = self.cast(active, s)
            h &= ta < self.tmax64[active]
            active = active[h]
            count[active] += 1
            last[active] = ta[h]
        if len(active):
            raise RuntimeError(f"crossings did not terminate after {max_iter} casts")
        return count


FRAME_MAGIC = b"ANTF"
BITS_MAGIC = b"ANTB"
# Receivers per batch of a frame: keeps the arrays of one batch near 100 MB.
FRAME_BATCH_RAYS = 1 << 20


def read_frame(path):
    data, receivers, samples = _read_header(path, FRAME_MAGIC, "frame")
    _check_size(path, "frame", data, 16 + 12 * (receivers + samples))
    points = np.frombuffer(data, dtype="<f4", count=3 * (receivers + samples), offset=16)
    points = points.reshape(receivers + samples, 3)
    if len(points) and not np.isfinite(points).all():
        raise InputError(f"frame file {path}: a receiver or sample is not finite")
    return (np.ascontiguousarray(points[:receivers], dtype=np.float32),
            np.ascontiguousarray(points[receivers:], dtype=np.float32))


def frame(argv):
    """The shadow rays of a frame: every receiver to every light sample.

    Times what a user of Embree pays per frame on one core: the scene's
    creation and commit (a first one-ray query commits it) plus an occlusion
    query of every ray (origin p, direction s - p, [0, 1], Embree's own
    interval), the arrays of each batch made beforehand and not timed; the
    fastest of --passes frames, each with a new scene. Writes the occlusion
    bits (bit i of receiver r's words: ray to sample i not occluded)."""
    ap = argparse.ArgumentParser(prog="embree_oracle.py frame", description=frame.__doc__)
    ap.add_argument("mesh")
    ap.add_argument("frame")
    ap.add_argument("out")
    ap.add_argument("--passes", type=int, default=1, metavar="N")
    args = ap.parse_args(argv)
    try:
        verts, tris = read_mesh(args.mesh)
        receivers, samples = read_frame(args.frame)
    except InputError as e:
        print(f"embree_oracle: error: {e}", file=sys.stderr)
        return 2
    # One core, the build included: Embree's task scheduler (TBB) sizes its
    # pool from the process's CPU affinity, so pin before it starts.
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError as e:
        print(f"embree_oracle: error: cannot import embreex ({e}); "
              f"run tests/oracle/setup_venv.sh and use its python (target/pyenv/bin/python)",
              file=sys.stderr)
        return 1
    import time
    n, m = len(receivers), len(samples)
    words = (m + 63) // 64
    per_batch = max(1, FRAME_BATCH_RAYS // max(m, 1))
    batches = []
    for start in range(0, n, per_batch):
        p = receivers[start:start + per_batch]
        origins = np.ascontiguousarray(np.repeat(p, m, axis=0))
        dirs = np.ascontiguousarray((samples[None, :, :] - p[:, None, :]).reshape(-1, 3))
        batches.append((origins, dirs.astype(np.float32)))
    one = (np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    best = (float("inf"), 0.0, 0.0)
    visible = None
    for _ in range(max(1, args.passes)):
        started = time.perf_counter()
        scene = rtcore_scene.EmbreeScene(robust=True)
        if len(verts) and len(tris):
            mesh = TriangleMesh(scene, verts, tris)  # noqa: F841 (kept alive)
        scene.run(one[0], one[1], dists=np.ones(1, np.float32), query="OCCLUDED")
        build = time.perf_counter() - started
        rays = 0.0
        answers = []
        for origins, dirs in batches:
            tfar = np.ones(len(origins), np.float32)
            started = time.perf_counter()
            occ = scene.run(origins, dirs, dists=tfar, query="OCCLUDED")
            rays += time.perf_counter() - started
            answers.append(occ != 0)
        if build + rays < best[0]:
            best = (build + rays, build, rays)
        visible = np.concatenate(answers) if answers else np.zeros(0, bool)
        del scene
    bits = np.zeros((n, words * 64), bool)
    bits[:, :m] = visible.reshape(n, m)
    # Little-endian bit order in little-endian words: bit i of word w is
    # sample 64 w + i.
    packed = np.packbits(bits, axis=1, bitorder="little")
    header = BITS_MAGIC + struct.pack("<III", VERSION, n, m)
    timing = struct.pack("<dd", best[1], best[2])
    tmp = args.out + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header + timing + packed.tobytes())
    os.replace(tmp, args.out)
    return 0


def main(argv=None):
    if argv is None:
        argv = sys.argv[1:]
    if argv and argv[0] == "frame":
        return frame(argv[1:])
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh")
    ap.add_argument("rays")
    ap.add_argument("out")
    ap.add_argument("--crossings", action="store_true",
                    help="count distinct surfaces crossed on (0, t_max) (flag bit 0)")
    ap.add_argument("--raw", action="store_true",
                    help="report Embree's answers without the open-interval boundary "
                         "corrections (flag bit 1)")
    ap.add_argument("--timing", metavar="FILE",
                    help="write 'occluded_seconds=S' to FILE: the wall time of one batch "
                         "occlusion query over all rays on one thread (a second call, "
                         "after the scene is committed)")
    ap.add_argument("--timing-passes", type=int, default=1, metavar="N",
                    help="with --timing, time N passes and write the fastest (default 1)")
    ap.add_argument("--crossing-eps", type=float, default=DEFAULT_EPS,
                    help=f"relative step past each hit (default {DEFAULT_EPS})")
    args = ap.parse_args(argv)
    if not (args.crossing_eps > 0 and np.isfinite(args.crossing_eps)):
        ap.error("--crossing-eps must be a positive finite number")

    try:
        verts, tris = read_mesh(args.mesh)
        orig, dirs, tmax = read_rays(args.rays)
    except InputError as e:
        print(f"embree_oracle: error: {e}", file=sys.stderr)
        return 2

    try:
        import embreex  # noqa: F401
    except ImportError as e:
        print(f"embree_oracle: error: cannot import embreex ({e}); "
              f"run tests/oracle/setup_venv.sh and use its python (target/pyenv/bin/python)",
              file=sys.stderr)
        return 1

    n = len(orig)
    caster = Caster(verts, tris, orig, dirs, tmax, args.crossing_eps)
    occ = caster.occluded()
    if args.timing:
        # embreex's run() loops rtcOccluded1 over the batch in C on this thread.
        # The fastest of --timing-passes passes: on a shared machine the slower
        # ones measure the other processes.
        import time
        elapsed = float("inf")
        for _ in range(max(1, args.timing_passes)):
            started = time.perf_counter()
            caster.occluded()
            elapsed = min(elapsed, time.perf_counter() - started)
        with open(args.timing, "w") as f:
            f.write(f"occluded_seconds={elapsed!r}\n")
    c_hit, c_t, prim, u, v = caster.closest(raw=False)
    inconsistent = int((c_hit & ~occ).sum())
    if args.raw:
        hit, t, prim, u, v = caster.closest(raw=True)
        cleared = 0
    else:
        hit, t = c_hit, c_t
        cleared_mask = occ & ~hit
        occ = occ & ~cleared_mask
        cleared = int(cleared_mask.sum())
    out = np.zeros(n, dtype=RESULT_DTYPE)
    out["occluded"] = occ
    out["t"] = np.where(hit, t, np.inf).astype(np.float32)
    out["prim"] = np.where(hit, prim.astype(np.int64) & 0xFFFFFFFF, NO_HIT)
    out["u"] = np.where(hit, u, 0.0)
    out["v"] = np.where(hit, v, 0.0)
    flags = 0
    if args.raw:
        flags |= FLAG_RAW
    if args.crossings:
        flags |= FLAG_CROSSINGS
        # Always from the corrected closest hit, also with --raw.
        out["crossings"] = caster.crossings(c_hit, c_t, max_iter=len(tris) + 2)

    header = OUT_MAGIC + struct.pack("<III", VERSION, n, flags)
    tmp = f"{args.out}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(header)
        f.write(out.tobytes())
    os.replace(tmp, args.out)

    msg = (f"embree_oracle: {n} rays, {len(tris)} triangles: {int(hit.sum())} hit, "
           f"{int(out['occluded'].sum())} occluded")
    if args.crossings:
        msg += f", {int(out['crossings'].sum())} crossings"
    if cleared:
        msg += f", {cleared} occlusions at t==0/t==t_max cleared"
    if inconsistent:
        msg += f", WARNING {inconsistent} rays hit but Embree said not occluded"
    print(msg, file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
