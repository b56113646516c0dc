// poa test part: a wall with a shelf held by a gusset under it (60 degrees from vertical).
// Sliced hollow at 0.3 mm layers, the shelf's first layer is bridge infill over the air
// beside the gusset and over its hollow inside, the strands 0.05 mm apart: each strip
// between two is a piece of the region over air.
cube([30, 4, 30]);
translate([0, 4, 20]) cube([30, 15, 3]);
translate([10, 4, 20]) rotate([0, 90, 0]) linear_extrude(10) polygon([[0, 0], [8.66, 0], [0, 15]]);
