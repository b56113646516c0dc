// A block with a round tunnel through it, printed standing: the tunnel's ceiling is a
// gradual overhang from both sides that closes at the crown, where the layer above bridges
// the last gap the rings leave (12 mm radius, 12 mm deep).
difference() {
    cube([40, 12, 25]);
    translate([20, -1, 0]) rotate([-90, 0, 0]) cylinder(r = 12, h = 14, $fn = 90);
}
