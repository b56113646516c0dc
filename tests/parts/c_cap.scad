// A C-shaped cap on a post, joined to it by a bar: its floating layer is a ring open on
// one side (a held-out part for Cura's support: the bar beside the post is over air).
cylinder(r = 4, h = 10, $fn = 48);
translate([0, 0, 10]) difference() {
    cylinder(r = 16, h = 3, $fn = 96);
    cylinder(r = 9, h = 7, center = true, $fn = 64);
    translate([0, 0, -1]) linear_extrude(5) polygon([[0, 0], [30, -12], [30, 12]]);
}
translate([0, 0, 10]) cylinder(r = 4, h = 3, $fn = 48);
rotate(180) translate([3, -1.5, 10]) cube([7, 3, 3]);
