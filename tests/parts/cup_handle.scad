// A mug's side with a handle: a torus on its side half sunk into a cylinder. The handle's
// underside is a gradual overhang that turns into the torus's inner and outer flanks; the
// layers above its rewritten rings stand on the moved perimeters.
cylinder(h = 30, r = 10, $fn = 64);
translate([10, 0, 15]) rotate([90, 0, 0])
    rotate_extrude(angle = 360, $fn = 64) translate([9, 0]) circle(r = 2.5, $fn = 24);
