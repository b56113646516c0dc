// A closed box with a domed ceiling inside (a squashed sphere, 32 mm across) over a
// 14 mm high room: the ceiling closes layer by layer round a shrinking hole, a gradual
// overhang on a 64-faceted ring right up to the top.
$fn = 64;
difference() {
    cube([36, 36, 30]);
    translate([2, 2, 2]) cube([32, 32, 14]);
    translate([18, 18, 16]) scale([1, 1, 0.7]) sphere(r = 16);
}
