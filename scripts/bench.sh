#!/usr/bin/env bash
# Throughput and peak memory of poa's commands on large G-code files.
#
#   bash scripts/bench.sh            # 50 MB plate, every command
#   SIZE_MB=100 bash scripts/bench.sh
#
# The plate is made from sample-gcode/rect_overhang_prusa_rel.gcode: its layers are repeated
# with every copy shifted in X/Y (a plate of many parts, printed layer by layer), until the file
# reaches SIZE_MB. Written to bench-data/ (git-ignored). Peak RSS from /usr/bin/time.
set -euo pipefail
cd "$(dirname "$0")/.."
size_mb=${SIZE_MB:-50}
mkdir -p bench-data
plate=bench-data/plate_${size_mb}mb.gcode
cargo build --release --quiet
if [ ! -f "$plate" ]; then
    python3 scripts/make_plate.py sample-gcode/rect_overhang_prusa_rel.gcode "$size_mb" "$plate"
fi
bytes=$(stat -c %s "$plate")
echo "file: $plate ($((bytes / 1024 / 1024)) MB)"
run() {
    local label=$1; shift
    # Warm the page cache so that we measure poa, not the disk.
    cat "$plate" >/dev/null
    local out
    out=$( { /usr/bin/time -f '%e %M' "$@" >/dev/null; } 2>&1 | tail -n 1)
    local secs=${out% *} rss_kb=${out#* }
    python3 -c "import sys; b,s,r=int(sys.argv[1]),float(sys.argv[2]),int(sys.argv[3]); \
print(f'{sys.argv[4]:<12} {s:7.2f} s {b/1048576/max(s,1e-3):8.1f} MB/s  peak RSS {r/1024:6.1f} MB')" \
        "$bytes" "$secs" "$rss_kb" "$label"
}
run "cp" cp "$plate" bench-data/copy.gcode
run "poa info" target/release/poa info "$plate"
run "poa analyze" target/release/poa analyze "$plate"
run "poa process" target/release/poa process "$plate" -o bench-data/out.gcode
run "poa check" target/release/poa check "$plate"
rm -f bench-data/copy.gcode bench-data/out.gcode
