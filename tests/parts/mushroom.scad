// poa test part: a mushroom (issue 19's benchmark part): a round stem 10 mm across and 10 mm
// tall under a cap 40 mm across and 3 mm thick, so one ring-shaped floating layer per copy.
$fn = 96;
cylinder(d = 10, h = 10);
translate([0, 0, 10]) cylinder(d = 40, h = 3);
