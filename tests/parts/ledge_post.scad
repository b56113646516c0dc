// A short post (8 x 8 x 3 mm) with a 6 mm ledge on top: low enough for PrusaSlicer's
// sequential printing ("complete objects"), where each copy starts again on the bed.
cube([8, 8, 3]);
translate([0, 0, 3]) cube([14, 8, 1]);
