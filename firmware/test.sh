#!/usr/bin/env bash
# Build fracfw's host unit tests with gcc (C99, warnings as errors, ASan + UBSan) with 8-bit octets
# and with emulated 16-bit octet storage (FW_OCTET16), and run them against the shared vectors.
set -euo pipefail
cd "$(dirname "$0")"
CC=${CC:-gcc}
out=${FW_BUILD_DIR:-build}
mkdir -p "$out"
flags=(-std=c99 -Wall -Wextra -Werror -pedantic -O1 -g -fno-omit-frame-pointer
       -fsanitize=address,undefined -fno-sanitize-recover=all -Iinclude)
for mode in 8 16; do
    extra=()
    [ "$mode" = 16 ] && extra=(-DFW_OCTET16)
    "$CC" "${flags[@]}" "${extra[@]}" src/fw_codec.c src/fw_engine.c src/fw_ctrl.c tests/test_fw.c \
        -o "$out/test_fw$mode" -lm
    "$out/test_fw$mode" ../crates/drive/testvectors
done
