// A pipe elbow lying on the bed: a quarter torus (bend radius 16 mm, tube 5 mm outer,
// 3.5 mm inner radius). Its second layer already hangs past the first one; PrusaSlicer
// draws the first layer in by its elephant-foot compensation.
$fn = 64;
translate([0, 0, 5]) rotate_extrude(angle = 90) translate([16, 0])
    difference() { circle(r = 5); circle(r = 3.5); }
