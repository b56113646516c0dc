// An overhang test strip: a 50 x 6 x 4 mm base, then five 10 mm wide steps whose +Y faces
// slope 30, 45, 55, 65 and 75 degrees from vertical over 6 mm of height, under a 2 mm cap.
// Gradual overhangs of every steepness side by side, each layer a little past the last.
angles = [30, 45, 55, 65, 75];
cube([50, 6, 4]);
for (i = [0:4]) {
    o = 6 * tan(angles[i]);
    translate([10 * i, 0, 4]) rotate([90, 0, 90])
        linear_extrude(10) polygon([[0, 0], [6, 0], [6 + o, 6], [6 + o, 8], [0, 8]]);
}
