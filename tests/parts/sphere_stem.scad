// A sphere on a stem: a 20 mm ball on a 6 mm stem 8 mm high. The ball's underside is a
// gradual overhang, steeper than any tolerance near the stem and flattening towards it.
$fn = 48;
cylinder(d = 6, h = 8.5);
translate([0, 0, 18]) sphere(d = 20);
