// Chamfered box: a 20 x 20 mm block 8 mm high widening over 4 mm up by 6.93 mm in Y (60
// degrees from vertical) and by 4 mm in X (45 degrees), under a 2 mm slab. Each layer of the
// slopes is a gradual overhang whose ring is wider on two sides than on the other two.
cube([20, 20, 8]);
translate([0, 0, 8]) hull() {
  cube([20, 20, 0.01]);
  translate([-4, -6.93, 4]) cube([28, 33.86, 0.01]);
}
translate([-4, -6.93, 12]) cube([28, 33.86, 2]);
