#!/usr/bin/env bash
# Worst-case instruction counts of fracfw's interrupt-time entry points, counted with valgrind's
# callgrind on the host build (x86-64, gcc -O2, 16-bit octet storage as on the C28x), and an
# estimate of C28x cycles per sample at 1 kHz and 10 kHz (the model and its assumptions:
# tools/cycles_report.py and README.md, "Interrupt timing"). Deterministic: the same sources and
# compiler give the same counts. Needs gcc, valgrind (with valgrind/callgrind.h), objdump, python3.
# Not run in CI (about a minute of valgrind). Usage: bash firmware/cycles.sh [BAUD] (default 115200)
set -euo pipefail
cd "$(dirname "$0")"
CC=${CC:-gcc}
baud=${1:-115200}
out=${FW_BUILD_DIR:-build}/cycles
rm -rf "$out"
mkdir -p "$out"
flags=(-std=c99 -Wall -Wextra -Werror -pedantic -O2 -DFW_OCTET16 -Iinclude)
"$CC" "${flags[@]}" -c src/fw_codec.c -o "$out/fw_codec.o"
"$CC" "${flags[@]}" -c src/fw_engine.c -o "$out/fw_engine.o"
"$CC" "${flags[@]}" -c src/fw_ctrl.c -o "$out/fw_ctrl.o"
"$CC" "${flags[@]}" -no-pie "$out/fw_codec.o" "$out/fw_engine.o" "$out/fw_ctrl.o" tools/cycles.c -o "$out/cycles"
# fracfw's own functions (including static ones gcc kept out of line): only these are counted
nm --defined-only "$out/fw_codec.o" "$out/fw_engine.o" "$out/fw_ctrl.o" |
    awk 'NF == 3 && ($2 == "T" || $2 == "t") { print $3 }' | sort -u >"$out/fracfw.syms"
echo "# fracfw interrupt timing: gcc $("$CC" -dumpfullversion) -O2 x86-64, callgrind, $baud baud"
echo
for rate in 1000 10000; do
    # octets on the line per sample period, each way (10 bits per octet), rounded up
    octets=$(( (baud + 10 * rate - 1) / (10 * rate) ))
    dir="$out/$rate"
    mkdir -p "$dir"
    cp "$out/fracfw.syms" "$dir/"
    valgrind --tool=callgrind --collect-atstart=no --dump-instr=yes --compress-pos=no \
        --compress-strings=no --callgrind-out-file="$dir/cg.out" "$out/cycles" "$rate" "$octets" \
        >"$dir/run.log" 2>"$dir/valgrind.log" || { cat "$dir/valgrind.log" "$dir/run.log"; exit 1; }
    python3 tools/cycles_report.py "$out/cycles" "$dir" "$rate" "$octets"
done
