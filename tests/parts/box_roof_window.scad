// A box with a roof and a window: four walls (2 mm thick, 30 x 30 mm, 12 mm high) with a
// 10 x 6 mm window in the front wall, closed by a 2 mm roof. The roof spans the box's inside,
// held by the walls all round (poa finds it as one wide region); the window's lintel bridges 10 mm.
difference() {
    cube([30, 30, 14]);
    translate([2, 2, -1]) cube([26, 26, 13]);
    translate([10, -1, 4]) cube([10, 4, 6]);
}
