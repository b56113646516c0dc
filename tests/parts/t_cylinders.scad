// A "T": a horizontal cylinder (radius 4, 40 mm long) on a vertical post of 8 mm. Its first
// layers are two wings anchored only where they meet the post.
$fn = 64;
cylinder(r = 4, h = 22);
translate([-20, 0, 24]) rotate([0, 90, 0]) cylinder(r = 4, h = 40);
