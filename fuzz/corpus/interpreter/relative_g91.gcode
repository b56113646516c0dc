; poa sample: hand-written; G91 relative positioning for X/Y/Z with extrusion, 3 layers of 0.2 mm, 10 mm square + 9.1 mm inner square per layer starting at (100,100); the file sets M82 (absolute E) first, but under G91 Marlin treats E as relative too, so the E words inside the G91 block are per-move amounts (0.0333 mm filament per mm); layer changes are relative Z moves (G1 Z0.2); G90 at the end restores absolute positioning (and absolute E); PrusaSlicer-style tags give the expected Z
G21 ; set units to millimeters
G90 ; use absolute coordinates
M82 ; use absolute distances for extrusion
G92 E0
M107
;LAYER_CHANGE
;Z:0.2
;HEIGHT:0.2
G1 Z0.2 F720
G1 X100 Y100 F10800
G91 ; relative positioning from here on (X, Y, Z and E)
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X10 E0.333
G1 Y10 E0.333
G1 X-10 E0.333
G1 Y-10 E0.333
G1 X0.45 Y0.45 F10800 ; travel to the inner loop
;TYPE:Perimeter
G1 F1800
G1 X9.1 E0.30303
G1 Y9.1 E0.30303
G1 X-9.1 E0.30303
G1 Y-9.1 E0.30303
G1 E-0.8 F2100 ; retract (relative under G91)
G1 X-0.45 Y-0.45 F10800 ; back to the outer corner (100,100)
;LAYER_CHANGE
;Z:0.4
;HEIGHT:0.2
G1 Z0.2 F720 ; up one layer (relative)
G1 E0.8 F2100 ; unretract (relative under G91)
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 Y10 E0.333
G1 X10 E0.333
G1 Y-10 E0.333
G1 X-10 E0.333
G1 X0.45 Y0.45 F10800 ; travel to the inner loop
;TYPE:Perimeter
G1 F1800
G1 Y9.1 E0.30303
G1 X9.1 E0.30303
G1 Y-9.1 E0.30303
G1 X-9.1 E0.30303
G1 E-0.8 F2100 ; retract (relative under G91)
G1 X-0.45 Y-0.45 F10800 ; back to the outer corner (100,100)
;LAYER_CHANGE
;Z:0.6
;HEIGHT:0.2
G1 Z0.2 F720 ; up one layer (relative)
G1 E0.8 F2100 ; unretract (relative under G91)
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X10 E0.333
G1 Y10 E0.333
G1 X-10 E0.333
G1 Y-10 E0.333
G1 X0.45 Y0.45 F10800 ; travel to the inner loop
;TYPE:Perimeter
G1 F1800
G1 X9.1 E0.30303
G1 Y9.1 E0.30303
G1 X-9.1 E0.30303
G1 Y-9.1 E0.30303
G1 E-0.8 F2100 ; retract (relative under G91)
G1 X-0.45 Y-0.45 F10800 ; back to the outer corner (100,100)
G90 ; absolute positioning again (Marlin: E is absolute again too, M82 still in force)
G92 E0
G1 Z10.6 F720 ; move print head up (absolute)
G1 X0 Y200 F3600 ; park
M107
M84 ; disable motors
; filament used [mm] = 7.63
