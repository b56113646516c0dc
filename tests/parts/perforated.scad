// A perforated plate: 30 x 30 x 3 mm pierced by a 7 x 7 grid of 1.6 mm holes 3.3 mm apart
// (walls of 1.7 mm between them, as a vent or a sieve), with a 1 mm lid over the left half
// from 3 mm up. The slicer prints one hole's wall right after the next one's and threads
// its perimeters between the holes; the lid's first layer bridges 21 holes.
$fn = 16;
difference() {
  union() {
    cube([30, 30, 3]);
    cube([15, 30, 4]);
  }
  for (i = [0:6], j = [0:6])
    translate([5.1 + i * 3.3, 5.1 + j * 3.3, -1]) cylinder(d = 1.6, h = 4);
}
