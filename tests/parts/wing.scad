// A wing: an 8 x 30 x 12 mm block with a flat-bottomed fin reaching 22 mm out of its top,
// tapering to a 10 mm wide, 1 mm thick edge. The fin's underside rises 1 mm over its
// 22 mm, so every layer of it reaches out past the one below by a few millimetres: a run
// of wide regions, each printed over the last one as rewritten.
cube([8, 30, 12]);
hull() {
    translate([0, 0, 10]) cube([8, 30, 2]);
    translate([30, 10, 11]) cube([1, 10, 1]);
}
