#!/usr/bin/env python3
"""Self-check of embree_oracle.py against analytic answers.

Run with the oracle venv's python (see setup_venv.sh):

    target/pyenv/bin/python tests/oracle/test_oracle_selfcheck.py

Prints one line per failure and 'N passed, M failed' at the end; exits 1 on any
failure.
"""
import math
import os
import struct
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ORACLE = os.path.join(HERE, "embree_oracle.py")
NO_HIT = 0xFFFFFFFF
INF = float("inf")

RESULT_DTYPE = np.dtype([("occluded", "<u4"), ("t", "<f4"), ("prim", "<u4"),
                         ("u", "<f4"), ("v", "<f4"), ("crossings", "<u4")])

passed = 0
failed = 0


def check(cond, name, detail=""):
    global passed, failed
    if cond:
        passed += 1
    else:
        failed += 1
        print(f"FAIL: {name} {detail}", flush=True)


def close(a, b, tol=1e-5):
    if math.isinf(b):
        return math.isinf(a) and (a > 0) == (b > 0)
    return abs(a - b) <= tol * max(1.0, abs(b))


# ---------------------------------------------------------------- file writers
def mesh_bytes(verts, tris):
    verts = np.asarray(verts, dtype="<f4").reshape(-1, 3)
    tris = np.asarray(tris, dtype="<u4").reshape(-1, 3)
    return (b"ANTM" + struct.pack("<III", 1, len(verts), len(tris))
            + verts.tobytes() + tris.tobytes())


def rays_bytes(rays):
    rays = np.asarray(rays, dtype="<f4").reshape(-1, 7)
    return b"ANTR" + struct.pack("<III", 1, len(rays), 0) + rays.tobytes()


TMP = tempfile.mkdtemp(prefix="oracle_selfcheck_")


def run_raw(mesh_data, ray_data, *flags):
    mp, rp, op = (os.path.join(TMP, n) for n in ("m.bin", "r.bin", "o.bin"))
    for p in (mp, rp, op):
        if os.path.exists(p):
            os.remove(p)
    with open(mp, "wb") as f:
        f.write(mesh_data)
    with open(rp, "wb") as f:
        f.write(ray_data)
    p = subprocess.run([sys.executable, ORACLE, mp, rp, op, *flags],
                       capture_output=True, text=True)
    return p, op


def run(verts, tris, rays, *flags):
    p, op = run_raw(mesh_bytes(verts, tris), rays_bytes(rays), *flags)
    if p.returncode != 0:
        raise RuntimeError(f"oracle failed rc={p.returncode}: {p.stderr}")
    check(p.stdout == "", "stdout empty on success", repr(p.stdout))
    data = open(op, "rb").read()
    magic = data[:4]
    version, n, fl = struct.unpack_from("<III", data, 4)
    check(magic == b"ANTO" and version == 1, "result header", f"{magic!r} v{version}")
    check(len(data) == 16 + 24 * n, "result size", f"{len(data)} for {n} rays")
    res = np.frombuffer(data, dtype=RESULT_DTYPE, offset=16, count=n)
    return res, fl


def expect(res, i, name, occ=None, t=None, prim=None, u=None, v=None, crossings=None, tol=1e-5):
    r = res[i]
    got = dict(occ=int(r["occluded"]), t=float(r["t"]), prim=int(r["prim"]), u=float(r["u"]),
               v=float(r["v"]), crossings=int(r["crossings"]))
    ok = True
    if occ is not None and got["occ"] != occ:
        ok = False
    if t is not None and not close(got["t"], t, tol):
        ok = False
    if prim is not None and got["prim"] != prim:
        ok = False
    if u is not None and not close(got["u"], u, tol):
        ok = False
    if v is not None and not close(got["v"], v, tol):
        ok = False
    if crossings is not None and got["crossings"] != crossings:
        ok = False
    want = {k: x for k, x in dict(occ=occ, t=t, prim=prim, u=u, v=v, crossings=crossings).items()
            if x is not None}
    check(ok, name, f"want {want} got {got}")


def ray(o, d, tmax):
    return list(o) + list(d) + [tmax]


# -------------------------------------------------------- 1. single triangles
def test_triangles():
    # T0: the unit right triangle in z=0. T1: a scalene triangle in z=0 at x in [3,6],
    # stored with permuted vertex indices so u/v must follow the index order.
    A, B, C = (5.0, 0.5, 0.0), (3.0, 0.0, 0.0), (4.0, 2.0, 0.0)
    verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), B, C, A]
    tris = [(0, 1, 2), (5, 3, 4)]  # T1 = (A, B, C)
    pu, pv = 0.2, 0.5
    P = [(1 - pu - pv) * A[k] + pu * B[k] + pv * C[k] for k in range(3)]
    # Embree's t is within about an ulp of exact, and which way it rounds depends
    # on the kernel Embree picks for the processor (for this ray 1.0 on some
    # machines, 0.99999994 on an AVX2 Zen 3). The oracle's open interval is
    # defined on the t Embree reports, so the boundary cases use that t.
    raw, _ = run(verts, tris, [ray((.25, .25, 1), (0, 0, -1), 10)], "--raw")
    t_embree = float(np.float32(raw[0]["t"]))
    check(abs(t_embree - 1.0) <= 4e-7, "Embree's t within a few ulps of 1", str(t_embree))
    one_up = float(np.nextafter(np.float32(t_embree), np.float32(2)))
    rays = [
        ray((.25, .25, 1), (0, 0, -1), 10),          # 0 plain hit
        ray((.25, .25, 1), (0, 0, -2), 10),          # 1 |d| = 2 -> t halves
        ray((.25, .25, 1), (0, 0, -1), 0.9),         # 2 t_max short of the triangle
        ray((-1, -1, 1), (0, 0, -1), 10),            # 3 miss
        ray((.25, .25, 1), (0, 0, -1), t_embree),    # 4 t == t_max exactly: open interval -> miss
        ray((.25, .25, 1), (0, 0, -1), one_up),      # 5 t_max one ulp past -> hit
        ray((.25, .25, -1), (0, 0, 1), 10),          # 6 back face hit
        ray((.1, .2, 3), (.1, .05, -1.5), 10),       # 7 oblique, unnormalised: hits (.3,.3,0) at t=2
        ray((.25, .25, 1), (0, 0, -1), INF),         # 8 t_max = +inf
        ray((.25, .25, 0), (0, 0, 1), 10),           # 9 origin on the triangle, pointing away: t=0 excluded
        ray((.6, .3, 4), (0, 0, -0.5), 10),          # 10 asymmetric barycentrics, t = 8
        ray((P[0], P[1], 2), (0, 0, -1), 10),        # 11 T1 with permuted indices
        ray((.25, .25, 1), (0, 0, -1), -5),          # 12 negative t_max -> nothing
        ray((.25, .25, 1), (0, 0, 1), 10),           # 13 pointing away
        ray((.25, .25, 1e-3), (0, 0, -1e-3), 10),    # 14 tiny direction: t = 1
        ray((.25, .25, 0), (0, 0, 0), 10),           # 15 zero direction on the surface: nothing
    ]
    for flags in ((), ("--crossings",)):
        res, fl = run(verts, tris, rays, *flags)
        tag = "tri" + ("+x" if flags else "")
        check(fl == (1 if flags else 0), f"{tag} flags", str(fl))
        cx = (lambda k: k) if flags else (lambda k: 0)
        expect(res, 0, f"{tag} hit", occ=1, t=1, prim=0, u=.25, v=.25, crossings=cx(1))
        expect(res, 1, f"{tag} scaled dir halves t", occ=1, t=.5, prim=0, u=.25, v=.25, crossings=cx(1))
        expect(res, 2, f"{tag} t_max short", occ=0, t=INF, prim=NO_HIT, u=0, v=0, crossings=0)
        expect(res, 3, f"{tag} miss", occ=0, t=INF, prim=NO_HIT, crossings=0)
        expect(res, 4, f"{tag} t == t_max is a miss", occ=0, t=INF, prim=NO_HIT, crossings=0)
        expect(res, 5, f"{tag} t_max one ulp past", occ=1, t=1, prim=0, crossings=cx(1))
        expect(res, 6, f"{tag} back face", occ=1, t=1, prim=0, u=.25, v=.25, crossings=cx(1))
        expect(res, 7, f"{tag} oblique unnormalised", occ=1, t=2, prim=0, u=.3, v=.3, crossings=cx(1))
        expect(res, 8, f"{tag} infinite t_max", occ=1, t=1, prim=0, crossings=cx(1))
        expect(res, 9, f"{tag} origin on surface", occ=0, t=INF, prim=NO_HIT, crossings=0)
        expect(res, 10, f"{tag} barycentrics u=x v=y", occ=1, t=8, prim=0, u=.6, v=.3, crossings=cx(1))
        expect(res, 11, f"{tag} permuted triangle u/v", occ=1, t=2, prim=1, u=pu, v=pv, crossings=cx(1))
        expect(res, 12, f"{tag} negative t_max", occ=0, t=INF, prim=NO_HIT, crossings=0)
        expect(res, 13, f"{tag} pointing away", occ=0, t=INF, prim=NO_HIT, crossings=0)
        expect(res, 14, f"{tag} tiny direction", occ=1, t=1, prim=0, crossings=cx(1), tol=1e-4)
        expect(res, 15, f"{tag} zero direction", occ=0, t=INF, prim=NO_HIT, crossings=0)

    # --raw exposes Embree's closed interval at t_max.
    res, fl = run(verts, tris, [rays[4], rays[0]], "--raw")
    check(fl == 2, "raw flag bit", str(fl))
    expect(res, 0, "raw: Embree hits at t == t_max", occ=1, t=1, prim=0)
    expect(res, 1, "raw: plain hit", occ=1, t=1, prim=0, u=.25, v=.25)


# ----------------------------------------------- 2. two parallel quads, crossings
def quad(z, x0=0.0, y0=0.0, s=1.0):
    v = [(x0, y0, z), (x0 + s, y0, z), (x0 + s, y0 + s, z), (x0, y0 + s, z)]
    return v, [(0, 1, 2), (0, 2, 3)]  # shared diagonal (x0,y0)-(x0+s,y0+s)


def merge(*parts):
    verts, tris = [], []
    for v, t in parts:
        base = len(verts)
        verts += v
        tris += [tuple(i + base for i in tri) for tri in t]
    return verts, tris


def test_quads():
    verts, tris = merge(quad(0.0), quad(1.0))  # prims 0,1 at z=0; 2,3 at z=1
    rays = [
        ray((.3, .6, -1), (0, 0, 1), 10),        # 0 through both
        ray((.5, .5, -1), (0, 0, 2), 10),        # 1 through both shared diagonals, |d|=2
        ray((.3, .6, -1), (0, 0, 1), 1.5),       # 2 stops between the quads
        ray((.3, .6, -1), (0, 0, 1), 2.0),       # 3 t_max exactly at the second quad
        ray((.3, .6, .5), (0, 0, -1), 10),       # 4 starts between, goes down
        ray((.3, .6, 0), (0, 0, 1), 10),         # 5 starts ON the lower quad
        ray((.1, .1, -1), (.2, .3, 1), 10),      # 6 oblique through both
        ray((.1, .1, -1), (.5, 0, 1), 10),       # 7 oblique, misses the upper quad (x=1.1)
        ray((2, 2, -1), (0, 0, 1), 10),          # 8 miss
        ray((.3, .6, 5), (0, 0, -1), 10),        # 9 from above, through both
        ray((.3, .6, 5), (0, 0, -1), 4.5),       # 10 from above, stops between
        ray((.3, .6, -1), (0, 0, 1), INF),       # 11 infinite t_max
        ray((.5, .5, .5), (1, 1, 0), 10),        # 12 parallel to the quads: nothing
        ray((.7, .2, -1), (0, 0, 0.25), 10),     # 13 short direction: t = 4 then 8
    ]
    res, fl = run(verts, tris, rays, "--crossings")
    check(fl == 1, "quads flags", str(fl))
    expect(res, 0, "quads: through both", occ=1, t=1, crossings=2)
    check(int(res[0]["prim"]) in (0, 1), "quads: first prim is lower quad", str(res[0]["prim"]))
    expect(res, 1, "quads: shared diagonal counted once per quad", occ=1, t=.5, crossings=2)
    expect(res, 2, "quads: t_max between", occ=1, t=1, crossings=1)
    expect(res, 3, "quads: t_max at second quad (open)", occ=1, t=1, crossings=1)
    expect(res, 4, "quads: start between", occ=1, t=.5, crossings=1)
    expect(res, 5, "quads: start on lower quad", occ=1, t=1, crossings=1)
    check(int(res[5]["prim"]) in (2, 3), "quads: start on lower quad hits upper", str(res[5]["prim"]))
    expect(res, 6, "quads: oblique both", occ=1, t=1, crossings=2)
    expect(res, 7, "quads: oblique one", occ=1, t=1, crossings=1)
    expect(res, 8, "quads: miss", occ=0, t=INF, prim=NO_HIT, crossings=0)
    expect(res, 9, "quads: from above", occ=1, t=4, crossings=2)
    check(int(res[9]["prim"]) in (2, 3), "quads: from above hits upper first", str(res[9]["prim"]))
    expect(res, 10, "quads: from above stops between", occ=1, t=4, crossings=1)
    expect(res, 11, "quads: infinite t_max", occ=1, t=1, crossings=2)
    expect(res, 12, "quads: parallel ray", occ=0, t=INF, crossings=0)
    expect(res, 13, "quads: short direction", occ=1, t=4, crossings=2)

    # Without --crossings the field is 0 and flag bit 0 is clear.
    res, fl = run(verts, tris, rays[:2])
    check(fl == 0 and res["crossings"].tolist() == [0, 0], "quads: no crossings without flag",
          f"{fl} {res['crossings'].tolist()}")

    # Coincident duplicate quads count as one surface; a third quad adds one.
    verts, tris = merge(quad(0.0), quad(0.0), quad(0.5))
    res, _ = run(verts, tris, [ray((.3, .6, -1), (0, 0, 1), 10), ray((.3, .6, -1), (0, 0, 1), 1.2)],
                 "--crossings")
    expect(res, 0, "duplicates: merged", occ=1, t=1, crossings=2)
    expect(res, 1, "duplicates: merged, stop before third", occ=1, t=1, crossings=1)


# ----------------------------------------------------------- 3. closed cube
def cube():
    v = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    idx = {p: i for i, p in enumerate(v)}
    tris = []
    for axis in range(3):
        for side in (0, 1):
            corners = [p for p in v if p[axis] == side]
            a, b = [k for k in range(3) if k != axis]
            corners.sort(key=lambda p: (p[a], p[b]))
            c00, c01, c10, c11 = (idx[p] for p in corners)
            tris += [(c00, c10, c11), (c00, c11, c01)]
    return v, tris


def test_cube():
    verts, tris = cube()
    rays = [
        ray((.5, .5, .5), (1, 0, 0), 10),         # inside -> one wall
        ray((-1, .3, .6), (1, 0, 0), 10),         # through two walls
        ray((-1, .3, .6), (1, 0, 0), 1.5),        # enters only
        ray((-1, -1, -1), (1, 1, 1), 10),         # along the main diagonal: corners (0,0,0), (1,1,1)
        ray((-1, .5, .5), (1, 0, 0), 10),         # through face centres (shared diagonals)
    ]
    res, _ = run(verts, tris, rays, "--crossings")
    expect(res, 0, "cube: from inside", occ=1, t=.5, crossings=1)
    expect(res, 1, "cube: through", occ=1, t=1, crossings=2)
    expect(res, 2, "cube: enters", occ=1, t=1, crossings=1)
    expect(res, 3, "cube: through two corners", occ=1, t=1, crossings=2)
    expect(res, 4, "cube: through face-diagonal points", occ=1, t=1, crossings=2)


# ------------------------------------------ 4. random soup vs float64 brute force
def brute(verts, tris, o, d, tmax):
    """All hits (t, prim, u, v, margin) of one ray, float64 Moeller-Trumbore."""
    v0, v1, v2 = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - v0
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
    ok = np.abs(det) > 1e-12
    return t, u, v, ok


def test_random():
    rng = np.random.default_rng(12345)
    nt = 60
    centres = rng.uniform(-1, 1, (nt, 1, 3))
    verts = (centres + rng.normal(0, 0.3, (nt, 3, 3))).reshape(-1, 3).astype(np.float32)
    tris = np.arange(3 * nt, dtype=np.uint32).reshape(nt, 3)
    nr = 3000
    o = rng.uniform(-2, 2, (nr, 3)).astype(np.float32)
    d = (rng.normal(0, 1, (nr, 3)) * rng.uniform(0.2, 5, (nr, 1))).astype(np.float32)
    tmax = rng.uniform(0, 3, nr).astype(np.float32)
    tmax[::7] = np.inf
    rays = np.concatenate([o, d, tmax[:, None]], axis=1)
    res, _ = run(verts, tris, rays, "--crossings")

    V = verts.astype(np.float64)
    T = tris.astype(np.int64)
    checked = skipped = bad = 0
    first_bad = None
    for i in range(nr):
        oi, di, tm = o[i].astype(np.float64), d[i].astype(np.float64), float(tmax[i])
        t, u, v, ok = brute(V, T, oi, di, tm)
        margin = np.minimum(np.minimum(u, v), 1 - u - v)
        inside = ok & (margin > 0) & (t > 0) & (t < tm)
        # Skip ambiguous rays: near an edge, near t=0 / t_max, near-coincident hits.
        near = ok & (np.abs(margin) < 1e-4) & (t > -1e-3) & (t < tm + 1e-3)
        ts = np.sort(t[inside])
        dl = np.linalg.norm(di)
        amb = near.any() or (ts.size and (ts[0] * dl < 1e-3 or (np.isfinite(tm) and (tm - ts[-1]) * dl < 1e-3)))
        amb = amb or (ts.size > 1 and (np.diff(ts) * dl).min() < 1e-3)
        amb = amb or (ok & (np.abs(t) < 1e-3 / dl) & (margin > -1e-4)).any()
        if np.isfinite(tm):
            amb = amb or (ok & (np.abs(t - tm) * dl < 1e-3) & (margin > -1e-4)).any()
        if amb:
            skipped += 1
            continue
        checked += 1
        r = res[i]
        if ts.size == 0:
            good = (r["occluded"] == 0 and math.isinf(r["t"]) and r["prim"] == NO_HIT
                    and r["crossings"] == 0)
        else:
            k = int(np.nonzero(inside & (t == ts[0]))[0][0])
            good = (r["occluded"] == 1 and close(float(r["t"]), ts[0], 1e-4) and int(r["prim"]) == k
                    and abs(r["u"] - u[k]) < 1e-4 and abs(r["v"] - v[k]) < 1e-4
                    and int(r["crossings"]) == ts.size)
        if not good:
            bad += 1
            if first_bad is None:
                first_bad = (i, r, ts[:3])
    check(bad == 0, "random soup vs brute force", f"{bad}/{checked} mismatches, first {first_bad}")
    check(checked > nr * 0.8, "random soup: enough unambiguous rays", f"{checked} checked, {skipped} skipped")
    hits = int((res["prim"] != NO_HIT).sum())
    multi = int((res["crossings"] > 1).sum())
    check(hits > 300 and multi > 50, "random soup: non-trivial", f"{hits} hits, {multi} with >1 crossing")


# ------------------------------------------------------ 5. edge cases & errors
def test_edges():
    verts, tris = quad(0.0)
    res, fl = run(verts, tris, np.zeros((0, 7)), "--crossings")
    check(len(res) == 0 and fl == 1, "zero rays")
    res, _ = run(np.zeros((0, 3)), np.zeros((0, 3)), [ray((0, 0, 1), (0, 0, -1), 10)], "--crossings")
    expect(res, 0, "empty mesh", occ=0, t=INF, prim=NO_HIT, crossings=0)
    res, _ = run(verts, np.zeros((0, 3)), [ray((.3, .3, 1), (0, 0, -1), 10)])
    expect(res, 0, "vertices but no triangles", occ=0, t=INF, prim=NO_HIT)
    # A single ray (embreex broadcasts a 1-row direction array; must still work).
    res, _ = run(verts, tris, [ray((.3, .6, 1), (0, 0, -4), 10)], "--crossings")
    expect(res, 0, "single ray", occ=1, t=.25, crossings=1)

    good_mesh = mesh_bytes(verts, tris)
    good_rays = rays_bytes([ray((.3, .3, 1), (0, 0, -1), 10)])
    bad_cases = {
        "mesh bad magic": (b"XNTM" + good_mesh[4:], good_rays),
        "rays bad magic": (good_mesh, b"ANTX" + good_rays[4:]),
        "mesh bad version": (good_mesh[:4] + struct.pack("<I", 2) + good_mesh[8:], good_rays),
        "rays bad version": (good_mesh, good_rays[:4] + struct.pack("<I", 0) + good_rays[8:]),
        "mesh truncated": (good_mesh[:-1], good_rays),
        "mesh truncated header": (good_mesh[:10], good_rays),
        "mesh empty file": (b"", good_rays),
        "rays truncated": (good_mesh, good_rays[:-4]),
        "mesh trailing bytes": (good_mesh + b"\0" * 4, good_rays),
        "rays trailing bytes": (good_mesh, good_rays + b"\0"),
        "rays count too big": (good_mesh, good_rays[:8] + struct.pack("<I", 2) + good_rays[12:]),
        "rays reserved != 0": (good_mesh, good_rays[:12] + struct.pack("<I", 1) + good_rays[16:]),
        "index out of range": (mesh_bytes(verts, [(0, 1, 4)]), good_rays),
        "NaN vertex": (mesh_bytes([(0, 0, 0), (1, 0, 0), (0, float("nan"), 0)], [(0, 1, 2)]), good_rays),
        "NaN ray origin": (good_mesh, rays_bytes([ray((float("nan"), 0, 0), (0, 0, 1), 1)])),
        "NaN t_max": (good_mesh, rays_bytes([ray((0, 0, 0), (0, 0, 1), float("nan"))])),
    }
    for name, (m, r) in bad_cases.items():
        p, op = run_raw(m, r, "--crossings")
        check(p.returncode == 2 and p.stderr.strip() != "" and p.stdout == "" and not os.path.exists(op),
              f"error: {name}", f"rc={p.returncode} stderr={p.stderr.strip()!r}")
    p = subprocess.run([sys.executable, ORACLE, os.path.join(TMP, "nope.bin"), os.path.join(TMP, "nope2.bin"),
                        os.path.join(TMP, "o.bin")], capture_output=True, text=True)
    check(p.returncode == 2 and "cannot read" in p.stderr, "error: missing file", p.stderr.strip())


def main():
    for test in (test_triangles, test_quads, test_cube, test_random, test_edges):
        try:
            test()
        except Exception as e:  # a crash counts as one failure, keep going
            check(False, test.__name__, f"raised {type(e).__name__}: {e}")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
