// Two pillars 6 mm apart under a 2 mm deck: a short bridge the slicer's bridge infill spans
// from pier to pier. `--bridges auto` keeps it as sliced.
cube([5, 10, 10]);
translate([11, 0, 0]) cube([5, 10, 10]);
translate([0, 0, 10]) cube([16, 10, 2]);
