// A shelf 22 mm deep off a wall, with a 4 x 14 mm slot through it. Cura with the outer wall
// first sets the slot's walls a little apart from the shelf's skin: a separate floating
// island of walls right beside the overhang region.
cube([20, 10, 25]);
difference() {
    translate([0, 10, 21]) cube([20, 22, 4]);
    translate([8, 14, 20]) cube([4, 14, 6]);
}
