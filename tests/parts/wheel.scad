// poa test part: a hub post with six 1.5 mm spokes and a rim 2 mm wide at 8 mm. The rim
// floats on the spokes, which are narrower than a contour and a perimeter each side.
$fn = 64;
cylinder(d = 8, h = 12);
translate([0, 0, 8]) {
    difference() {
        cylinder(d = 36, h = 2);
        translate([0, 0, -1]) cylinder(d = 32, h = 4);
    }
    for (a = [0:60:300]) rotate([0, 0, a]) translate([0, -0.75, 0]) cube([17, 1.5, 2]);
}
