// poa test part: a bridge (Print-on-Air paper, Table 1: 40 x 20 span, 10 thick) between two
// 10 x 20 pillars; the span starts at Z 10. 60 x 20 x 20 overall.
span = [40, 20, 10];
pillar = 10;
lift = 10;
for (x = [0, pillar + span[0]]) translate([x, 0, 0]) cube([pillar, span[1], lift + span[2]]);
translate([0, 0, lift]) cube([2 * pillar + span[0], span[1], span[2]]);
