// Two shelves with a hole: a 10 mm back wall 30 mm wide carrying two 15 mm shelves at 8 and
// 16 mm, each with an 8 mm round hole. The shelves are overhangs with a hole in the region.
$fn = 64;
cube([10, 30, 20]);
for (z = [8, 16])
    translate([0, 0, z]) difference() {
        cube([25, 30, 2]);
        translate([18, 15, -1]) cylinder(d = 8, h = 4);
    }
