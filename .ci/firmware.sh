#!/usr/bin/env bash
# Firmware CI: release build, clippy on the target, size budget, and (when QEMU is
# installed) a boot of the emulated build on netduinoplus2.
#
# Assumes `rustup target add thumbv7em-none-eabihf`. Uses the cargo aliases of
# .cargo/config.toml. Budgets can be overridden: FLASH_MAX, RAM_MAX (bytes).
set -euo pipefail

cd "$(dirname "$0")/.."

TARGET=thumbv7em-none-eabihf
ELF=target/$TARGET/firmware/dca-firmware
QEMU_DIR=target/qemu
QEMU_ELF=$QEMU_DIR/$TARGET/firmware/dca-firmware
FLASH_MAX=${FLASH_MAX:-65536} # 64 KiB
RAM_MAX=${RAM_MAX:-16384}     # 16 KiB
PASS_LINE="dca-firmware: 100 ticks ok"

step() { printf '\n== %s\n' "$*"; }

step "release build"
cargo fw

step "clippy (board and qemu builds, -D warnings)"
cargo fw-clippy
cargo clippy -p dca-firmware --no-deps --target "$TARGET" --features qemu \
    --target-dir "$QEMU_DIR" -- -D warnings

step "size"
SYSROOT=$(rustc --print sysroot)
LLVM_SIZE=$(ls "$SYSROOT"/lib/rustlib/*/bin/llvm-size 2>/dev/null | head -n 1 || true)
if [ -z "$LLVM_SIZE" ]; then
    echo "llvm-size not found: rustup component add llvm-tools" >&2
    exit 1
fi
"$LLVM_SIZE" -A "$ELF" | grep -Ev '^\.(debug|comment|ARM)|^Total|^$'
# Berkeley format: text (vector table, code, rodata), data, bss (.bss and .uninit).
read -r TEXT DATA BSS _ < <("$LLVM_SIZE" -B "$ELF" | tail -n 1)
FLASH=$((TEXT + DATA))
RAM=$((DATA + BSS))
echo "flash (text+data): $FLASH B of $FLASH_MAX B budget"
echo "static RAM (data+bss): $RAM B of $RAM_MAX B budget (stack not included)"
fail=0
if [ "$FLASH" -gt "$FLASH_MAX" ]; then
    echo "FAIL: flash $FLASH B > $FLASH_MAX B" >&2
    fail=1
fi
if [ "$RAM" -gt "$RAM_MAX" ]; then
    echo "FAIL: static RAM $RAM B > $RAM_MAX B" >&2
    fail=1
fi
[ "$fail" -eq 0 ] || exit 1

if ! command -v qemu-system-arm >/dev/null 2>&1; then
    step "qemu-system-arm not installed: emulated boot skipped"
    exit 0
fi

step "qemu build and boot (netduinoplus2)"
cargo fw-qemu
# stdout carries the defmt frames (semihosting); stderr the pass line.
status=0
timeout 60 qemu-system-arm -machine netduinoplus2 -nographic \
    -semihosting-config enable=on,target=native -icount shift=3,sleep=off \
    -kernel "$QEMU_ELF" >"$QEMU_DIR/defmt.bin" 2>"$QEMU_DIR/qemu.stderr" || status=$?
cat "$QEMU_DIR/qemu.stderr"
if command -v defmt-print >/dev/null 2>&1; then
    defmt-print -e "$QEMU_ELF" <"$QEMU_DIR/defmt.bin" || true
fi
if [ "$status" -eq 124 ]; then
    echo "FAIL: QEMU run timed out after 60 s" >&2
    exit 1
elif [ "$status" -ne 0 ]; then
    echo "FAIL: QEMU exited with status $status" >&2
    exit 1
elif ! grep -qF "$PASS_LINE" "$QEMU_DIR/qemu.stderr"; then
    echo "FAIL: QEMU exited 0 without '$PASS_LINE'" >&2
    exit 1
fi
echo "ok: $PASS_LINE"
