#!/usr/bin/env python3
"""Checks the symbols of the bare-metal libantumbra.a against the header.

Usage: check_bare_metal_symbols.py include/antumbra.h libantumbra.a

- The archive defines exactly the functions the header declares outside
  `#if defined(ANTUMBRA_HAS_STD)` blocks (so the header's marks are true both
  ways: nothing missing, nothing undeclared).
- Every symbol the archive leaves undefined is one a bare-metal toolchain
  supplies without an operating system: the ARM EABI run-time helpers
  (__aeabi_*, from libgcc), a few pure functions of the C library (memcmp,
  memcpy, memmove, memset, fmin, fmax and their float forms, from newlib) and
  Rust's own internal symbols (_R..., defined in the same archive or by the
  allocator shim). No malloc, no I/O, no threads, no time, no abort.
"""
import re
import subprocess
import sys

ALLOWED_UNDEFINED = re.compile(
    r"^(__aeabi_\w+|mem(cmp|cpy|move|set)|f(min|max)f?|_R\w+)$"
)


def header_functions(path):
    """Functions declared in the header, split by whether the bare-metal build has them."""
    everywhere, hosted_only = set(), set()
    stack = []  # one bool per open #if: whether it excludes bare metal
    for line in open(path):
        stripped = line.strip()
        if stripped.startswith("#if"):
            stack.append(stripped == "#if defined(ANTUMBRA_HAS_STD)")
        elif stripped.startswith("#endif"):
            stack.pop()
        elif stripped.startswith("#else") or stripped.startswith("#elif"):
            stack[-1] = False
        match = re.search(r"\b(antumbra_\w+)\(", line)
        if match and not stripped.startswith(("*", "/*", "#")) and "(*" not in line:
            (hosted_only if any(stack) else everywhere).add(match.group(1))
    return everywhere, hosted_only


def archive_symbols(path):
    defined, undefined = set(), set()
    out = subprocess.run(["arm-none-eabi-nm", path], check=True, capture_output=True, text=True).stdout
    exported = set()
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0] == "U":
            undefined.add(parts[1])
        elif len(parts) == 3:
            defined.add(parts[2])
            if parts[1] == "T" and parts[2].startswith("antumbra_"):
                exported.add(parts[2])
    return exported, undefined - defined


def main(argv):
    if len(argv) != 3:
        print(__doc__)
        return 2
    everywhere, hosted_only = header_functions(argv[1])
    exported, unresolved = archive_symbols(argv[2])
    problems = []
    for name in sorted(everywhere - exported):
        problems.append(f"{name} is declared for bare metal but missing from the library")
    for name in sorted(exported - everywhere):
        where = "marked hosted-only" if name in hosted_only else "not declared"
        problems.append(f"{name} is in the library but {where} in the header")
    for name in sorted(unresolved):
        if not ALLOWED_UNDEFINED.match(name):
            problems.append(f"the library needs {name}, which bare metal does not provide")
    for problem in problems:
        print(f"  {problem}")
    print(
        f"bare-metal symbols: {len(exported)} functions exported as the header declares "
        f"({len(hosted_only)} hosted-only absent); undefined: "
        f"{', '.join(sorted(n for n in unresolved if not n.startswith('_R')))}"
    )
    if problems:
        print("check_bare_metal_symbols: FAILED")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
