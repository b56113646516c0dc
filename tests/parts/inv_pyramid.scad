// poa test part: a stem under an inverted pyramid flaring at 55 degrees from vertical.
// Sliced hollow (0 % infill), each layer of the flare is a ring of two perimeters, its
// outer side past the layer below (a gradual overhang), its inner side over the ring below.
$fn = 48;
cylinder(d = 8, h = 6);
translate([0, 0, 6]) hull() {
    cube([8, 8, 0.01], center = true);
    translate([0, 0, 8]) cube([8 + 2 * 8 * tan(55), 8 + 2 * 8 * tan(55), 0.01], center = true);
}
