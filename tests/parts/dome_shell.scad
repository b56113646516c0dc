// A hemispherical shell standing open side down (outer radius 18, 1.8 mm thick): its inside
// is a cavity that closes in faster each layer. Below about 60 degrees from vertical the
// inner wall steps in by less than a bead (the strip past the tolerance lies in the hole of
// the layer below, where no strand's centre line runs); higher up by more.
$fn = 96;
difference() {
    sphere(r = 18);
    sphere(r = 16.2);
    translate([-20, -20, -20]) cube([40, 40, 20]);
}
