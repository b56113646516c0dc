// A lamp shade: a hollow half sphere, outer radius 22 mm, wall 2 mm, open side down. Its
// inside is a dome ceiling closing over a hole of the part that is never to be filled.
$fn = 64;
difference() {
    sphere(r = 22);
    sphere(r = 20);
    translate([0, 0, -30]) cube(60, center = true);
}
