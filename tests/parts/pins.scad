// 36 pins 1.2 mm across on a strip: tiny islands, each wiped after its loop (PrusaSlicer's
// wipe moves pull filament back on about half of each layer's moves with E).
for (i = [0:5]) for (j = [0:5]) translate([i * 4, j * 4, 0]) cylinder(d = 1.2, h = 6, $fn = 16);
translate([0, -6, 0]) cube([20, 2, 1]);
