#!/usr/bin/env bash
# The bare-metal C library, proven on an emulated Cortex-M4 (make test's
# `embedded` step):
#   1. builds libantumbra.a without std for thumbv7em-none-eabihf and checks its
#      symbols: exactly the functions the header declares outside
#      `#if defined(ANTUMBRA_HAS_STD)`, and nothing that needs an operating system;
#   2. bakes the example's scene with the hosted library (c_examples/embedded/
#      make_bakes.c) into a header the firmware compiles in;
#   3. builds c_examples/embedded/embedded_demo.c for the host (hosted library) and
#      as firmware for QEMU's mps2-an386 (Cortex-M4F, newlib, semihosting), runs
#      both and compares them (tools/compare_embedded.py, which also shows that it
#      can fail);
#   4. builds and runs the masks-only firmware, and reports the flash and RAM of
#      both images;
#   5. runs c_examples/bad_input.c as firmware: the bad-input checks that apply
#      without std, which the hosted build runs too (c-examples step).
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
CARGO=${CARGO:-cargo}
TARGET=thumbv7em-none-eabihf
TARGET_DIR=${CARGO_TARGET_DIR:-$ROOT/target}
case $TARGET_DIR in /*) ;; *) TARGET_DIR=$ROOT/$TARGET_DIR ;; esac
BUILD=$ROOT/c_examples/build/embedded
E=$ROOT/c_examples/embedded
mkdir -p "$BUILD"
cd "$ROOT"

echo "== the bare-metal library"
"$CARGO" build -p antumbra-ffi --release --no-default-features --target $TARGET
"$CARGO" build -p antumbra-ffi --release
BARE_LIB=$TARGET_DIR/$TARGET/release/libantumbra.a
HOST_LIB=$TARGET_DIR/release/libantumbra.a
python3 tools/check_bare_metal_symbols.py include/antumbra.h "$BARE_LIB"

echo "== the scene and its bakes (hosted library)"
CFLAGS_HOST=(-std=c99 -O2 -g -Wall -Wextra -Werror -I"$ROOT/include" -I"$BUILD")
gcc "${CFLAGS_HOST[@]}" "$E/make_bakes.c" "$HOST_LIB" -lm -lpthread -ldl -o "$BUILD/make_bakes"
"$BUILD/make_bakes" "$BUILD/embedded_data.h"

echo "== the example on the host"
gcc "${CFLAGS_HOST[@]}" "$E/embedded_demo.c" "$HOST_LIB" -lm -lpthread -ldl -o "$BUILD/embedded_demo_host"
"$BUILD/embedded_demo_host" > "$BUILD/host.out"

ARM_FLAGS=(-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -O2 -g -std=c99 -Wall -Wextra -Werror
           -ffunction-sections -fdata-sections -DANTUMBRA_NO_STD -I"$ROOT/include" -I"$BUILD" -I"$E")
ARM_LINK=(-T "$E/mps2_an386.ld" -nostartfiles --specs=nano.specs --specs=rdimon.specs -Wl,--gc-sections
          -Wl,--no-warn-execstack)
firmware() { # NAME SOURCE [DEFINES...]
    local name=$1 source=$2
    shift 2
    arm-none-eabi-gcc "${ARM_FLAGS[@]}" "$@" "$source" "$E/firmware_memory.c" "$E/startup.c" "${ARM_LINK[@]}" \
        "$BARE_LIB" -lm -o "$BUILD/$name.elf"
}
run_firmware() { # NAME: runs it in QEMU, its output into NAME.out; fails when it does
    local status=0
    timeout 300 qemu-system-arm -M mps2-an386 -nographic -monitor none -serial none \
        -semihosting-config enable=on,target=native -kernel "$BUILD/$1.elf" > "$BUILD/$1.out" 2>&1 || status=$?
    if [ $status -ne 0 ]; then
        cat "$BUILD/$1.out"
        echo "check_embedded: $1 stopped with status $status under QEMU"
        return 1
    fi
}

echo "== the example as Cortex-M4 firmware, under QEMU"
firmware embedded_demo "$E/embedded_demo.c"
run_firmware embedded_demo
grep '^info:' "$BUILD/embedded_demo.out" || true
python3 tools/compare_embedded.py "$BUILD/host.out" "$BUILD/embedded_demo.out"
python3 tools/compare_embedded.py --self-test "$BUILD/host.out"

echo "== the masks-only firmware"
firmware embedded_masks "$E/embedded_demo.c" -DMASKS_ONLY
run_firmware embedded_masks
if ! diff <(grep '^masks:' "$BUILD/host.out") <(grep '^masks:' "$BUILD/embedded_masks.out"); then
    echo "check_embedded: the masks-only firmware's masks differ from the host's"
    exit 1
fi
report() { # NAME LABEL: flash = code + read-only data + initial data; RAM = data + bss + heap peak + stack
    local sizes flash static heap stack
    sizes=$(arm-none-eabi-size -A "$BUILD/$1.elf")
    flash=$(awk '$1 ~ /^\.(text|rodata|ARM\.exidx|ARM\.extab|init_array|data)$/ {s += $2} END {print s}' <<< "$sizes")
    static=$(awk '$1 ~ /^\.(data|bss)$/ {s += $2} END {print s}' <<< "$sizes")
    heap=$(sed -n "s/^info: $3: heap peak \([0-9]*\) bytes.*/\1/p" "$BUILD/$1.out")
    stack=$(sed -n "s/^info: $3: heap peak [0-9]* bytes, stack \([0-9]*\) bytes/\1/p" "$BUILD/$1.out")
    awk -v label="$2" -v flash="$flash" -v static="$static" -v heap="$heap" -v stack="$stack" 'BEGIN {
        ram = static + heap + stack
        printf "%-22s flash %7d bytes (%5.1f KiB); RAM %7d bytes (%5.1f KiB) = static %d + heap peak %d + stack %d\n",
            label, flash, flash / 1024, ram, ram / 1024, static, heap, stack
    }'
}
report embedded_masks "masks-only firmware:" masks
report embedded_demo "full example firmware:" "full example"

echo "== bad input on bare metal"
firmware bad_input "$ROOT/c_examples/bad_input.c"
run_firmware bad_input
tail -n 1 "$BUILD/bad_input.out"

echo "check_embedded: passed"
