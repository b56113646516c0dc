// poa test part: a triangular overhang (Print-on-Air paper, Table 1: isosceles, base 35,
// height 18.75, 5 thick), its base along a 10 x 35 block, from Z 10.
base = 35;
height = 18.75;
thick = 5;
block = 10;
lift = 10;
cube([block, base, lift + thick]);
translate([block, 0, lift])
    linear_extrude(height = thick) polygon([[0, 0], [height, base / 2], [0, base]]);
