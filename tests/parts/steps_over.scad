// Stepped ledge: a 10 x 20 mm block 16 mm high with six steps 0.6 mm high, each reaching
// 1.2 mm farther out than the one below (about 63 degrees from vertical), under a 2 mm slab.
// PrusaSlicer lays each step as a bridge anchored over the block's sparse infill, and the
// last strand of that bridge ends over a gap of the infill below.
cube([10, 20, 16]);
for (i = [1:6]) translate([10, 0, 10 + i * 0.6]) cube([i * 1.2, 20, 0.6]);
translate([0, 0, 13.6]) cube([17.2, 20, 2]);
