// poa test part: a pipe (outer radius 8, bore 5, 30 long) lying on its side on two feet.
// Its underside is a gradual overhang; sliced hollow (0 % infill) each wall is two
// perimeters round a void, and low on the bore's sides the inner perimeter steps over it.
$fn = 96;
translate([0, 0, 9]) rotate([0, 90, 0]) difference() {
    cylinder(r = 8, h = 30);
    translate([0, 0, -1]) cylinder(r = 5, h = 32);
}
translate([0, -3, 0]) cube([4, 6, 2]);
translate([26, -3, 0]) cube([4, 6, 2]);
