// A bracket: a 6 x 20 x 30 mm plate standing on the bed, with a block on its side from
// Z 12 to 30 whose underside is a concave quarter round (radius 14): a fillet that starts
// as a thin strip along the plate's side and reaches 14 mm out at the top.
$fn = 80;
cube([6, 20, 30]);
difference() {
    translate([6, 0, 12]) cube([14, 20, 18]);
    translate([20, -1, 12]) rotate([-90, 0, 0]) cylinder(r = 14, h = 22);
}
