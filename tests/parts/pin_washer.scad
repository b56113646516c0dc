// A washer on a thin pin: a wide first floating layer over a pin whose inside holds only a
// stroke or two of sparse infill.
cylinder(h = 8, r = 3, $fn = 32);
translate([0, 0, 8]) cylinder(h = 2.4, r = 12, $fn = 64);
