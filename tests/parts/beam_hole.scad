// A post with a 20 mm beam out at 10 mm and a round 5 mm hole through the beam near its
// tip: the strips beside the hole are narrower than a contour and a perimeter.
$fn = 48;
difference() {
    union() {
        cube([8, 8, 14]);
        translate([8, 0, 10]) cube([20, 8, 4]);
    }
    translate([22, 4, 0]) cylinder(d = 5, h = 30);
}
