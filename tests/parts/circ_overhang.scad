// poa test part: a half-disc overhang (Print-on-Air paper, Table 1: radius 12.5, 5 thick) on
// the side of a 10 x 25 block; the disc starts at Z 10 and its flat side meets the block.
r = 12.5;
thick = 5;
block = 10;
lift = 10;
$fn = 180;
cube([block, 2 * r, lift + thick]);
translate([block, r, lift])
    intersection() {
        cylinder(r = r, h = thick);
        translate([0, -r, 0]) cube([r, 2 * r, thick]);
    }
