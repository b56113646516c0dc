// Two upside-down frustums on posts: one flaring at about 42 degrees from vertical (each
// layer within the tolerance of the one below) and one at about 63 degrees (a gradual
// overhang: every layer a thin ring beyond the one below).
$fn = 64;
cylinder(r = 5, h = 5);
translate([0, 0, 5]) cylinder(r1 = 5, r2 = 14, h = 10);
translate([25, 0, 0]) {
    cylinder(r = 4, h = 6);
    translate([0, 0, 6]) cylinder(r1 = 4, r2 = 12, h = 4);
}
