// A boat hull: two spheres' hull cut flat near its bottom, so the sides flare out fast over
// the first layers and the bow's tip flares most (a region at the bow whose zone runs on
// as a thin arm along each side).
$fn = 64;
module hullshape()
    hull() {
        translate([-12, 0, 10]) scale([1, 0.9, 1]) sphere(r = 10);
        translate([10, 0, 10]) scale([1.6, 0.6, 1]) sphere(r = 8);
    }
translate([0, 0, -2]) intersection() {
    hullshape();
    translate([-40, -20, 2]) cube([80, 40, 8]);
}
