#!/usr/bin/env bash
# 200 seeded PMSM records (fracid sim, seeded motor parameters and noise), fitted by the many-file
# mode of `fracid time` and by one process per file; checks that both give the same models and
# prints the wall times. Usage: bash docs/examples/fleet_bench.sh [WORKDIR]
#   FRACID   the CLI (default target/release/fracid)   N   records (default 200)
set -euo pipefail
FRACID=${FRACID:-target/release/fracid}
N=${N:-200}
W=${1:-$(mktemp -d)}
mkdir -p "$W/records" "$W/fleet" "$W/single"
for i in $(seq 0 $((N - 1))); do
    f=$(printf '%s/records/rec_%03d.csv' "$W" "$i")
    [ -s "$f" ] && continue
    # a motor of the line: the paper's model with seeded spread of its gain and time constants
    read -r K A1 A2 < <(awk -v s="$i" 'BEGIN { srand(s + 1);
        printf "%.4f %.6f %.9f\n", 6.77 * (0.95 + 0.1 * rand()), 0.0064 * (0.9 + 0.2 * rand()),
               0.000028 * (0.9 + 0.2 * rand()) }')
    # 3048 samples of the paper's PRBS at 0.1 ms, plus seeded white noise (sd 0.05) on y
    "$FRACID" sim --model "$K/($A2 s^1.78 + $A1 s^0.89 + 1)" --prbs --prbs-amplitude 1 \
        --dt 1e-4 --t-end 0.3048 |
        awk -F, -v s="$i" 'BEGIN { srand(1000 + s); OFS = "," }
            /^[-0-9.]/ { u1 = rand(); if (u1 < 1e-12) u1 = 1e-12; u2 = rand();
                         $3 = $3 + 0.05 * sqrt(-2 * log(u1)) * cos(6.283185307179586 * u2) }
            { print }' > "$f"
done
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
t0=$(date +%s.%N)
"$FRACID" time "$W/records" --out "$W/fleet" --quiet > "$W/fleet.log" || true
t1=$(date +%s.%N)
for f in "$W"/records/*.csv; do
    b=$(basename "$f" .csv)
    "$FRACID" time "$f" --json --quiet > "$W/single/$b.json" 2> /dev/null || true
done
t2=$(date +%s.%N)
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
python3 - "$W" "$t0" "$t1" "$t2" <<'PY'
import json, sys, pathlib
w = pathlib.Path(sys.argv[1]); t0, t1, t2 = map(float, sys.argv[2:5])
same = diff = 0
for s in sorted((w / "single").glob("*.json")):
    a = json.loads(s.read_text())["model"]
    b = json.loads((w / "fleet" / (s.stem + ".time.json")).read_text())["model"]
    same += a == b
    diff += a != b
summary = json.loads((w / "fleet" / "time-summary.json").read_text())
print(f"records {len(list((w / 'records').glob('*.csv')))}, failed in the fleet {summary['failed']}, "
      f"jobs {summary['jobs']}")
print(f"models identical to the one-by-one fits: {same}, different: {diff}")
print(f"many-file mode: {t1 - t0:.2f} s; one process per file: {t2 - t1:.2f} s; "
      f"speed-up {(t2 - t1) / (t1 - t0):.2f}x")
PY
