// poa test part: a torus lying flat, 40 mm across, its tube 12 mm thick: gradual overhangs
// round its underside, walls stepping inward over its top. (Binary STL: openscad
// --export-format binstl.)
$fn = 96;
translate([0, 0, 6]) rotate_extrude() translate([14, 0]) circle(r = 6, $fn = 64);
