#!/usr/bin/env python3
"""Builds a large plate from one PrusaSlicer file: every layer is printed N times, each copy
shifted in X/Y, like a plate of many identical parts. Usage: make_plate.py IN SIZE_MB OUT [LAYERS]
(LAYERS: keep only the first LAYERS layers, e.g. those below the part's first overhang, for a
plate without regions)."""
import re
import sys

src, size_mb, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
max_layers = int(sys.argv[4]) if len(sys.argv) > 4 else None
text = open(src, encoding="utf-8", errors="surrogateescape").read()
# The end G-code, statistics and config block are written once, after the last layer.
text, tail_sep, tail = text.partition("\n; filament used [mm]")
head, sep, rest = text.partition(";LAYER_CHANGE\n")
layers = (sep + rest).split(";LAYER_CHANGE\n")[1:]
if max_layers is not None:
    layers = layers[:max_layers]
body_len = sum(len(l) for l in layers)
copies = max(1, (size_mb * 1024 * 1024) // max(body_len, 1) + 2)
cols = int(copies ** 0.5) + 1
coord = re.compile(r"([XY])(-?\d*\.?\d+)")


def shift(block, dx, dy):
    def f(m):
        v = float(m.group(2)) + (dx if m.group(1) == "X" else dy)
        return f"{m.group(1)}{v:.3f}"
    lines = []
    for line in block.splitlines(keepends=True):
        if line.startswith(("G1", "G0")):
            code, semi, comment = line.partition(";")
            line = coord.sub(f, code) + semi + comment
        lines.append(line)
    return "".join(lines)


with open(out, "w", encoding="utf-8", errors="surrogateescape") as f:
    f.write(f"; poa benchmark plate: {copies} copies of {src}\n")
    f.write(head)
    for layer in layers:
        marker, _, body = layer.partition(";AFTER_LAYER_CHANGE")
        f.write(";LAYER_CHANGE\n" + marker)
        for i in range(copies):
            dx, dy = (i % cols) * 60.0, (i // cols) * 30.0
            f.write(";AFTER_LAYER_CHANGE" + shift(body, dx, dy) if body else "")
    f.write(tail_sep + tail)
print(f"{out}: {copies} copies")
