// A 40 x 26 mm plate, 3 mm thick, on a round post 10 mm across and 14 mm tall, with two
// 8 x 6 mm windows between the post and the plate's ends: a wide first floating layer whose
// loops grow from the post and round the windows.
$fn = 64;
cylinder(d = 10, h = 14);
translate([0, 0, 14]) difference() {
    translate([-20, -13, 0]) cube([40, 26, 3]);
    for (x = [-14, 6]) translate([x, -3, -1]) cube([8, 6, 5]);
}
