#!/usr/bin/env bash
# Throughput and peak memory of poa's commands on large G-code files.
#
#   bash scripts/bench.sh                 # 10 MB plates, every command
#   SIZE_MB=100 bash scripts/bench.sh     # 1, 10, 100 ... any size
#   SRC=sample-gcode/tri_overhang_prusa_rel.gcode FLAT_LAYERS=20 bash scripts/bench.sh
#                                         # another part; FLAT_LAYERS: its layers below the
#                                         # first overhang (no plate without regions if unset)
#   REAL=12 bash scripts/bench.sh         # a real plate instead: PrusaSlicer re-slices 12
#                                         # copies of PART (default tests/parts/circ_overhang)
#                                         # at LAYER mm (default 0.1), so no two copies share
#                                         # a footprint as tiled copies do
#
# Two plates are made from sample-gcode/rect_overhang_prusa_rel.gcode: its layers repeated with
# every copy shifted in X/Y (a plate of many parts printed layer by layer) until the file
# reaches SIZE_MB. "regions": all 100 layers, so every copy has its overhang (one region per
# copy, rewritten by `process`). "no regions": only the 50 layers below the overhang, so
# nothing is rewritten and `process` passes every layer through. Written to bench-data/
# (git-ignored). Peak RSS from /usr/bin/time; `cp` of the same file is the reference.
set -euo pipefail
cd "$(dirname "$0")/.."
size_mb=${SIZE_MB:-10}
mkdir -p bench-data
cargo build --release --quiet
src=${SRC:-sample-gcode/rect_overhang_prusa_rel.gcode}
if [ -z "${SRC:-}" ]; then
    flat_layers=${FLAT_LAYERS:-50}
else
    flat_layers=${FLAT_LAYERS:-}
fi
stem=$(basename "$src" .gcode)
run() {
    local plate=$1 label=$2; shift 2
    local bytes
    bytes=$(stat -c %s "$plate")
    # Warm the page cache so that we measure poa, not the disk.
    cat "$plate" >/dev/null
    local out
    out=$( { /usr/bin/time -f '%e %M' "$@" >/dev/null; } 2>&1 | tail -n 1)
    local secs=${out% *} rss_kb=${out#* }
    python3 -c "import sys; b,s,r=int(sys.argv[1]),float(sys.argv[2]),int(sys.argv[3]); \
print(f'{sys.argv[4]:<14} {s:7.2f} s {b/1048576/max(s,1e-3):8.1f} MB/s  peak RSS {r/1024:6.1f} MB')" \
        "$bytes" "$secs" "$rss_kb" "$label"
}
bench_all() {
    local plate=$1
    run "$plate" "cp" cp "$plate" bench-data/copy.gcode
    run "$plate" "poa info" target/release/poa info "$plate"
    run "$plate" "poa analyze" target/release/poa analyze "$plate"
    run "$plate" "poa process" target/release/poa process "$plate" -o bench-data/out.gcode
    run "$plate" "poa check" target/release/poa check "$plate"
    rm -f bench-data/copy.gcode bench-data/out.gcode
}
if [ -n "${REAL:-}" ]; then
    part=${PART:-tests/parts/circ_overhang.stl}
    layer=${LAYER:-0.1}
    plate=bench-data/real_$(basename "$part" .stl)_x${REAL}_${layer}.gcode
    [ -f "$plate" ] || prusa-slicer --load sample-gcode/config/prusaslicer-mk3s-pla.ini \
        --duplicate "$REAL" --layer-height "$layer" --export-gcode -o "$plate" "$part" >/dev/null
    echo "== $plate ($(( $(stat -c %s "$plate") / 1024 / 1024 )) MB, real plate of $REAL copies)"
    bench_all "$plate"
    exit 0
fi
kinds=regions
[ -n "$flat_layers" ] && kinds="regions no-regions"
for kind in $kinds; do
    plate=bench-data/plate_${stem}_${size_mb}mb_${kind}.gcode
    if [ ! -f "$plate" ]; then
        if [ "$kind" = regions ]; then
            python3 scripts/make_plate.py "$src" "$size_mb" "$plate" >/dev/null
        else
            python3 scripts/make_plate.py "$src" "$size_mb" "$plate" "$flat_layers" >/dev/null
        fi
    fi
    echo "== $plate ($(( $(stat -c %s "$plate") / 1024 / 1024 )) MB, $kind)"
    bench_all "$plate"
done
