// A 40 x 24 x 16 block with vertical holes of every kind the proof meets: two straight
// through-holes, a blind hole from below roofed at 8 mm, a hole narrowing upward (a cone:
// its wall overhangs inward), one widening upward, and a 10 mm slot. The holes rising
// straight are proven layer after layer; the others go to the exact path where they change.
$fn = 40;
difference() {
  cube([40, 24, 16]);
  translate([5, 5, -1]) cylinder(d = 4, h = 30);
  translate([5, 19, -1]) cylinder(d = 3, h = 30);
  translate([14, 6, -1]) cylinder(d = 6, h = 9);
  translate([14, 18, -1]) cylinder(d1 = 8, d2 = 2, h = 17.01);
  translate([24, 6, -1]) cylinder(d1 = 2, d2 = 8, h = 17.01);
  hull() {
    translate([32, 10, -1]) cylinder(d = 5, h = 30);
    translate([32, 19, -1]) cylinder(d = 5, h = 30);
  }
}
