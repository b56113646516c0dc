// A hook: a 6 x 10 mm post 25 mm high with an arm reaching 18 mm out at the top, and a lip
// rising 4 mm at the arm's end. The arm's underside is an overhang anchored on one side.
cube([6, 10, 25]);
translate([0, 0, 20]) cube([24, 10, 5]);
translate([20, 0, 25]) cube([4, 10, 4]);
