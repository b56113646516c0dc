// Two arms sloped at 60 deg from vertical, rising from a 10 x 10 mm central block: each arm
// (6 mm thick, 10 mm wide) leans out 60 deg from vertical, so every layer's edge hangs
// tan(60) x layer height past the one below: about 0.35 mm at 0.2 mm layers.
cube([10, 10, 4]);
for (s = [-1, 1])
    translate([5, 0, 2])
        multmatrix([[1, 0, s * tan(60), 0], [0, 1, 0, 0], [0, 0, 1, 0]])
            translate([-3, 0, 0]) cube([6, 10, 10]);
