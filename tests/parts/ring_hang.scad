// poa test part: a ring (24 mm across, 2 mm wide, 2 mm thick) held at 8 mm by one bar
// through a 6 mm post, 1.5 mm wide: the ring's first layer floats but where the bar's
// ends meet it. (Binary STL: openscad --export-format binstl.)
cylinder(d = 6, h = 12, $fn = 40);
translate([0, 0, 8]) {
    difference() {
        cylinder(d = 24, h = 2, $fn = 96);
        translate([0, 0, -1]) cylinder(d = 20, h = 4, $fn = 96);
    }
    translate([-11, -0.75, 0]) cube([22, 1.5, 2]);
}
