// A ring (a 4 mm tube bent to a 9 mm radius) tilted 30 degrees on a post, joined by a
// square spoke: most of its layers carry two short gradual overhangs (the tube's underside
// where it rises and where it falls), each a ring a few millimetres long.
$fn = 64;
cylinder(d = 6, h = 14);
translate([0, 0, 16]) rotate([30, 0, 0]) rotate_extrude($fn = 96) translate([9, 0]) circle(d = 4, $fn = 32);
translate([0, 0, 14]) rotate([30, 0, 0]) translate([-1.5, -10, -1.5]) cube([3, 10, 3]);
