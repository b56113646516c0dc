// A plain cylinder to print in spiral-vase mode: the input of `poa deform` (issue 15).
// 30 mm across, 15 mm tall, 180 facets (PrusaSlicer's vase mode follows them).
cylinder(d = 30, h = 15, $fn = 180);
