#!/usr/bin/env python3
"""Compares the embedded example's output on the device with the host's.

Usage: compare_embedded.py HOST_OUTPUT DEVICE_OUTPUT
       compare_embedded.py --self-test HOST_OUTPUT

Every line must be equal, except:
  - "info:" lines (the device's memory figures), which are not compared;
  - "values NAME: BITS..." lines (floats as IEEE-754 bits in hex), whose floats
    must be equal within FLOAT_BOUND_ULPS units in the last place of the largest
    magnitude of that output. Why a bound and not equality: the hosted build's
    glam does its Vec3A/Vec4 arithmetic in SSE2 lanes and the Cortex-M4 build in
    scalar code, so some sums of products (the glossy and MRT shading, up to
    bands² × grid² terms) are added in another order. Reassociating a sum of n
    float terms changes it by at most about n · 2^-24 · Σ|terms| (worst case;
    the outputs are of the size of their largest terms), and the observed
    difference is about one unit in the last place. 16 units is sixteen times
    what is observed and far below what any real divergence (a wrong
    coefficient, a lost term) produces. Masks, soft-shadow bits and every other
    line must match exactly.

--self-test checks that the comparison can fail: a copy of HOST_OUTPUT with one
mask bit changed, and one with a float moved beyond the bound, must both be
refused, and one with a float moved by one unit in the last place accepted.
"""
import struct
import sys

FLOAT_BOUND_ULPS = 16


def floats(field):
    return [struct.unpack("<f", struct.pack("<I", int(word, 16)))[0] for word in field.split()]


def ulp_of(magnitude):
    """The spacing of floats at `magnitude` (at least the smallest normal's)."""
    if magnitude < 2.0**-126:
        return 2.0**-149
    exponent = struct.unpack("<I", struct.pack("<f", magnitude))[0] >> 23 & 0xFF
    return 2.0 ** (exponent - 127 - 23)


def compare(host_lines, device_lines):
    """Returns (problems, notes)."""
    host = [line for line in host_lines if not line.startswith("info:")]
    device = [line for line in device_lines if not line.startswith("info:")]
    problems, notes = [], []
    if len(host) != len(device):
        problems.append(f"{len(host)} compared lines on the host, {len(device)} on the device")
    for h, d in zip(host, device):
        if h.startswith("values ") and d.startswith("values "):
            h_name, h_bits = h.split(":", 1)
            d_name, d_bits = d.split(":", 1)
            if h_name != d_name:
                problems.append(f"'{h_name}' on the host, '{d_name}' on the device")
                continue
            a, b = floats(h_bits), floats(d_bits)
            if len(a) != len(b):
                problems.append(f"{h_name}: {len(a)} floats on the host, {len(b)} on the device")
                continue
            differing = sum(1 for x, y in zip(a, b) if x != y)
            bound = FLOAT_BOUND_ULPS * ulp_of(max((abs(x) for x in a), default=0.0))
            worst = max((abs(x - y) for x, y in zip(a, b)), default=0.0)
            if worst > bound:
                problems.append(f"{h_name[7:]}: a float differs by {worst:.3g} (bound {bound:.3g})")
            elif differing:
                notes.append(f"{h_name[7:]}: {differing} of {len(a)} floats differ, by at most {worst:.3g} "
                             f"(bound {bound:.3g})")
            else:
                notes.append(f"{h_name[7:]}: all {len(a)} floats identical")
        elif h != d:
            problems.append(f"host:   {h.rstrip()}\n    device: {d.rstrip()}")
    return problems, notes


def self_test(host_lines):
    mask_line = next(i for i, line in enumerate(host_lines) if line.startswith("masks:"))
    flipped = list(host_lines)
    flipped[mask_line] = flipped[mask_line].replace("fnv ", "fnv 1", 1)[:-2] + "\n"
    value_line = next(i for i, line in enumerate(host_lines) if line.startswith("values bake glossy"))

    def moved(ulps):
        lines = list(host_lines)
        name, bits = lines[value_line].split(":", 1)
        words = bits.split()
        largest = max(range(len(words)), key=lambda i: abs(floats(words[i])[0]))
        words[largest] = f"{int(words[largest], 16) + ulps:08x}"
        lines[value_line] = f"{name}: {' '.join(words)}\n"
        return lines

    checks = [
        ("a changed mask checksum", flipped, False),
        (f"a float moved by {FLOAT_BOUND_ULPS + 1} units in the last place", moved(FLOAT_BOUND_ULPS + 1), False),
        ("a float moved by one unit in the last place", moved(1), True),
    ]
    ok = True
    for what, lines, accepted in checks:
        problems, _ = compare(host_lines, lines)
        if (not problems) != accepted:
            print(f"compare_embedded self-test: {what} was {'refused' if problems else 'accepted'}")
            ok = False
    print(f"compare_embedded self-test: {'passed' if ok else 'FAILED'} ({len(checks)} cases)")
    return 0 if ok else 1


def main(argv):
    if len(argv) == 3 and argv[1] == "--self-test":
        return self_test(open(argv[2]).readlines())
    if len(argv) != 3:
        print(__doc__)
        return 2
    problems, notes = compare(open(argv[1]).readlines(), open(argv[2]).readlines())
    for note in notes:
        print(f"  {note}")
    for problem in problems:
        print(f"  DIFFERS: {problem}")
    print(f"compare_embedded: {'FAILED' if problems else 'device and host agree'}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
