// A block with a ledge sloping 23 degrees from horizontal (67 from vertical) on one side:
// each 0.2 mm layer reaches 0.48 mm past the one below, more than a bead's width.
cube([20, 20, 20]);
hull() {
    translate([20, 0, 8]) cube([0.01, 20, 6]);
    translate([32, 0, 13]) cube([0.01, 20, 1]);
}
