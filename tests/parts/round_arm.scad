// A wall hook: a 30 x 5 x 45 mm plate standing on the bed, with an arm 26 mm out of it, 14 mm
// wide, flat on top at 33 mm and rounded underneath (a half round of radius 7), ending in a
// 6 mm lip. The arm's underside is a gradual overhang from the vertical to the flat.
$fn = 96;
cube([30, 5, 45]);
translate([8, 0, 0]) {
    hull() {
        translate([7, 5, 26]) rotate([-90, 0, 0]) cylinder(r = 7, h = 26);
        translate([0, 5, 32]) cube([14, 26, 1]);
    }
    translate([0, 27, 26]) cube([14, 4, 13]);
}
