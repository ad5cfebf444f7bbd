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
all, and at least one must exist: legacy roots in the rasterizer
(`antumbra_core::hemi::`) make such builds run it several times slower.
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


def check(binary, chosen, what, none_chosen):
    """Fails on any legacy SSE instruction in the functions of BINARY for which
    chosen(name, body) holds (WHAT names them), and when there are none."""
    checked, offenders = 0, []
    for name, body in functions(binary):
        if not chosen(name, body):
            continue
        checked += 1
        for address, mnemonic, operands in legacy(body):
            offenders.append(f"{name}: {address}: {mnemonic} {operands}")
    if checked == 0:
        sys.exit(f"{binary}: {none_chosen}")
    if offenders:
        print(f"legacy SSE instructions in {what}:")
        print("\n".join(offenders))
        sys.exit(1)
    print(f"{checked} {what}, none with a legacy SSE instruction")


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--all-avx":
        prefix = sys.argv[2]
        check(
            sys.argv[3],
            lambda name, _: name.startswith(prefix),
            f"{prefix} functions of the AVX build",
            f"no function starts with {prefix}",
        )
    elif len(sys.argv) == 2:
        check(
            sys.argv[1],
            lambda _, body: any("%ymm" in operands for _, _, operands in body),
            "functions that run 256-bit AVX code",
            "no function uses 256-bit registers; is this the release library?",
        )
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
