// An open bowl: the lower half of a spherical shell (outer radius 21 mm, 2 mm thick) on a
// 4 mm stem. Its flank flares out a little more with each layer: gradual overhangs all the
// way up, each rewrite moving the outline the next layer stands on.
$fn = 96;
cylinder(r = 4, h = 12);
translate([0, 0, 32]) difference() {
    sphere(r = 21);
    sphere(r = 19);
    translate([-25, -25, 0]) cube([50, 50, 25]);
}
