// A 60 x 16 x 20 mm block with horizontal bolt holes of 3, 5, 8 and 12 mm at 8 mm height,
// and a 6 mm lip at the front whose underside is a 45-degree chamfer. The chamfer's ring is
// a thin strip layer after layer; near the top of the 12 mm hole it runs into the hole's
// ceiling closing beside it, in one region.
difference() {
  union() {
    cube([60, 16, 20]);
    translate([0, -6, 14]) cube([60, 6, 6]);
    translate([0, 0, 14]) rotate([0, 90, 0]) linear_extrude(60) polygon([[0, 0], [6, 0], [0, -6]]);
  }
  for (d = [[3, 8], [5, 20], [8, 34], [12, 50]])
    translate([d[1], -7, 8]) rotate([-90, 0, 0]) cylinder(d = d[0], h = 30, $fn = 32);
}
