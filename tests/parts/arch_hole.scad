// A wall with a horizontal hole and a round-topped doorway, as printed standing: the
// hole's ceiling and the arch's top are gradual overhangs that flatten, layer by layer,
// into the bridge at their crown (each layer wider than a bead past the one below near
// the top).
$fn = 64;
difference() {
    translate([-15, -5, 0]) cube([30, 10, 20]);
    // Doorway: 8 wide, 6 straight, then a half circle of radius 4.
    translate([-11, -6, -1]) cube([8, 12, 7]);
    translate([-7, 6, 6]) rotate([90, 0, 0]) cylinder(r = 4, h = 12);
    // Horizontal hole of 8 mm across the wall.
    translate([7, 6, 10]) rotate([90, 0, 0]) cylinder(d = 8, h = 12);
}
