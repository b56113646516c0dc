// poa test part: a 90-degree rectangular cantilever (Print-on-Air paper, Table 1: 40 x 20 x 10).
// A 10 x 20 column, 20 high; at Z 10 a slab runs 40 mm past it, so with 0.2 mm layers the
// first layer printed over air is at Z 10.2.
cantilever = [40, 20, 10];  // free length (X), width (Y), thickness (Z)
column = 10;                // column depth along X
lift = 10;                  // free height under the slab
cube([column, cantilever[1], lift + cantilever[2]]);
translate([0, 0, lift]) cube([column + cantilever[0], cantilever[1], cantilever[2]]);
