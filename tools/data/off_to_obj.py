#!/usr/bin/env python3
"""Convert a plain-text OFF mesh (e.g. CGAL's data/meshes/armadillo.off) into a Wavefront OBJ.

Usage: python3 tools/data/off_to_obj.py IN.off OUT.obj [--comment TEXT]...
  Writes to stdout when OUT.obj is "-". Python 3 standard library only.

- `v` lines carry the exact numeric text of the OFF (nothing is parsed and re-printed,
  so nothing is rounded); each coordinate is still checked to be a finite number.
- `f` lines are 1-based, as OBJ requires (OFF is 0-based). Polygons with more than
  3 corners are split into triangle fans (0,1,2), (0,2,3), ...; the count is reported.
- The header is one line naming the input file and this script, then one `# TEXT` line
  per --comment (source, credit). Lines end in "\\n".

Only the plain `OFF` keyword is accepted (not COFF/NOFF/STOFF/4OFF/nOFF/binary OFF).
`#` comments and blank lines are skipped. Anything else unexpected is an error:
a vertex line with other than 3 numbers, a face index out of range or not an integer,
a face with fewer than 3 corners, or counts that do not match the header. Extra tokens
after a face's indices (an optional per-face colour in OFF) are dropped and counted.
"""
import math
import os
import sys


def fail(msg):
    sys.stderr.write("off_to_obj: " + msg + "\n")
    sys.exit(1)


def content_lines(text):
    """Yield (line number, tokens) for each line that is not blank or a comment."""
    for num, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if line:
            yield num, line.split()


def convert(text, name, comments):
    lines = content_lines(text)
    stats = {"comment_lines": sum(1 for l in text.splitlines() if "#" in l),
             "polygons": 0, "face_extra_tokens": 0}

    try:
        num, toks = next(lines)
    except StopIteration:
        fail(name + ": empty file")
    if toks[0] != "OFF":
        fail("%s:%d: expected the keyword OFF, got %r" % (name, num, toks[0]))
    toks = toks[1:]  # the counts may follow the keyword on the same line
    if not toks:
        try:
            num, toks = next(lines)
        except StopIteration:
            fail(name + ": missing counts line")
    if len(toks) != 3 or not all(t.isdigit() for t in toks):
        fail("%s:%d: expected 'vertices faces edges', got %r" % (name, num, " ".join(toks)))
    nv, nf, _ne = (int(t) for t in toks)

    out = ["# %s (OFF) converted by tools/data/off_to_obj.py" % os.path.basename(name)]
    for c in comments:
        if "\n" in c or "\r" in c:
            fail("--comment must be a single line")
        out.append("# " + c)

    for i in range(nv):
        try:
            num, toks = next(lines)
        except StopIteration:
            fail("%s: only %d of %d vertices" % (name, i, nv))
        if len(toks) != 3:
            fail("%s:%d: vertex %d has %d fields, expected 3 (colour/normal fields are not supported)"
                 % (name, num, i, len(toks)))
        for t in toks:
            try:
                ok = math.isfinite(float(t))
            except ValueError:
                ok = False
            if not ok:
                fail("%s:%d: vertex %d: bad coordinate %r" % (name, num, i, t))
        out.append("v " + " ".join(toks))

    ntri = 0
    for i in range(nf):
        try:
            num, toks = next(lines)
        except StopIteration:
            fail("%s: only %d of %d faces" % (name, i, nf))
        if not toks[0].isdigit():
            fail("%s:%d: face %d: bad corner count %r" % (name, num, i, toks[0]))
        n = int(toks[0])
        if n < 3 or len(toks) < 1 + n:
            fail("%s:%d: face %d: %d corners, %d indices" % (name, num, i, n, len(toks) - 1))
        idx = []
        for t in toks[1:1 + n]:
            if not t.isdigit() or int(t) >= nv:
                fail("%s:%d: face %d: index %r out of range 0..%d" % (name, num, i, t, nv - 1))
            idx.append(int(t) + 1)
        stats["face_extra_tokens"] += len(toks) - 1 - n
        if n > 3:
            stats["polygons"] += 1
        for k in range(1, n - 1):  # triangle fan around the first corner
            out.append("f %d %d %d" % (idx[0], idx[k], idx[k + 1]))
            ntri += 1

    rest = next(lines, None)
    if rest is not None:
        fail("%s:%d: unexpected data after %d faces" % (name, rest[0], nf))

    stats.update(vertices=nv, faces=nf, triangles=ntri)
    return "\n".join(out) + "\n", stats


def main(argv):
    args, comments = [], []
    it = iter(argv)
    for a in it:
        if a == "--comment":
            try:
                comments.append(next(it))
            except StopIteration:
                fail("--comment needs a value")
        elif a.startswith("--comment="):
            comments.append(a[len("--comment="):])
        else:
            args.append(a)
    if len(args) != 2:
        fail("usage: off_to_obj.py IN.off OUT.obj|- [--comment TEXT]...")
    src, dst = args
    with open(src, "r", encoding="ascii", newline="") as f:
        text = f.read()
    obj, st = convert(text, src, comments)
    if dst == "-":
        sys.stdout.write(obj)
    else:
        with open(dst, "w", encoding="ascii", newline="\n") as f:
            f.write(obj)
    sys.stderr.write(
        "%s: %d vertices, %d faces -> %d triangles (%d polygons fanned, %d extra face tokens "
        "dropped, %d comment lines skipped)\n"
        % (os.path.basename(src), st["vertices"], st["faces"], st["triangles"], st["polygons"],
           st["face_extra_tokens"], st["comment_lines"]))


if __name__ == "__main__":
    main(sys.argv[1:])
