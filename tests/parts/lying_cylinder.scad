// A cylinder lying on a narrow block: its underside a gradual overhang on both sides,
// flat at the bottom and vertical at the equator.
translate([-15, -2, 0]) cube([30, 4, 3.5]);
translate([-15, 0, 13]) rotate([0, 90, 0]) cylinder(d = 20, h = 30, $fn = 96);
