#!/usr/bin/env python3
"""Checks that no function running 256-bit AVX code also runs legacy SSE code.

Usage: check_avx_encoding.py BINARY
       check_avx_encoding.py --all-avx PREFIX BINARY

A legacy (non-VEX) SSE instruction executed while the upper halves of the
vector registers hold data makes the processor save or merge those halves, and
in a loop that costs more than the work itself. The compiler encodes its own
SSE code in VEX inside `#[target_feature(enable = "avx")]` functions, so legacy
instructions there come from inline assembly, as libm's x86 square roots are
(core calls `geom::sqrtf` and its siblings instead). The check disassembles
BINARY (the release libantumbra.so), takes every function that names a `%ymm`
register, and fails on any instruction in it that names an `%xmm` register with
a mnemonic not starting with `v` (legacy SSE). It also fails when no function
names a `%ymm` register, so it cannot pass on a binary without the AVX paths.

With `--all-avx PREFIX`, BINARY is a library built with AVX for the whole
crate (`RUSTFLAGS="-C target-feature=+avx2,+fma"`, as `-C target-cpu=native`
builds are), where every instruction the compiler emits is VEX-encoded: every
function whose name starts with PREFIX must hold no legacy SSE instruction at
all, and at least one must exist. Engines built that way run the
rasterizer (`antumbra_core::hemi::`) several times slower for each legacy root.
"""
import re
import subprocess
import sys

FUNCTION = re.compile(r"^[0-9a-f]+ <(.+)>:$")
INSTRUCTION = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$")


def functions(binary):
    """(name, [(address, mnemonic, operands)]) for every function of BINARY."""
    listing = subprocess.run(
        ["objdump", "-d", "--no-show-raw-insn", "-C", binary],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    name, body = None, []
    for line in listing.splitlines():
        start = FUNCTION.match(line)
        if start:
            if name is not None:
                yield name, body
            name, body = start.group(1), []
            continue
        instruction = INSTRUCTION.match(line)
        if name is not None and instruction:
            body.append(instruction.groups())
    if name is not None:
        yield name, body


def legacy(body):
    """The instructions of BODY that name an `%xmm` register without VEX."""
    return [
        (address, mnemonic, operands)
        for address, mnemonic, operands in body
        if "%xmm" in operands and not mnemonic.startswith("v")
    ]


def check_all_avx(prefix, binary):
    """Fails on any legacy SSE instruction in the functions named PREFIX..."""
    checked, offenders = 0, []
    for name, body in functions(binary):
        if not name.startswith(prefix):
            continue
        checked += 1
        for address, mnemonic, operands in legacy(body):
            offenders.append(f"{name}: {address}: {mnemonic} {operands}")
    if checked == 0:
        sys.exit(f"{binary}: no function starts with {prefix}")
    if offenders:
        print(f"legacy SSE instructions in {prefix} functions of an AVX build:")
        print("\n".join(offenders))
        sys.exit(1)
    print(f"{checked} {prefix} functions of the AVX build, none with a legacy SSE instruction")


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--all-avx":
        check_all_avx(sys.argv[2], sys.argv[3])
        return
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    with_avx, offenders = 0, []
    for name, body in functions(sys.argv[1]):
        if not any("%ymm" in operands for _, _, operands in body):
            continue
        with_avx += 1
        for address, mnemonic, operands in legacy(body):
            offenders.append(f"{name}: {address}: {mnemonic} {operands}")
    if with_avx == 0:
        sys.exit(f"{sys.argv[1]}: no function uses 256-bit registers; is this the release library?")
    if offenders:
        print("legacy SSE instructions in functions that run 256-bit AVX code:")
        print("\n".join(offenders))
        sys.exit(1)
    print(f"{with_avx} functions run 256-bit AVX code, none of them legacy SSE instructions")


if __name__ == "__main__":
    main()
