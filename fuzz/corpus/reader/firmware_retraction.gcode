; poa sample: hand-written; firmware retraction: G10 (retract) / G11 (recover) around every travel instead of E moves, relative E (M83), 3 layers of 0.2 mm, two 10 mm squares per layer at (100,100) and (115,100); M207/M208 set the firmware retraction (0.8 mm at 35 mm/s)
G21 ; set units to millimeters
G90 ; use absolute coordinates
M83 ; use relative distances for extrusion
M207 S0.8 F2100 Z0 ; firmware retraction length/speed/lift
M208 S0 F2100 ; firmware recover extra length/speed
M107
;LAYER_CHANGE
;Z:0.2
;HEIGHT:0.2
G1 Z0.2 F720
G1 X100 Y100 F10800
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X110 Y100 E0.333
G1 X110 Y110 E0.333
G1 X100 Y110 E0.333
G1 X100 Y100 E0.333
G10 ; retract
G1 X115 Y100 F10800
G11 ; unretract
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X125 Y100 E0.333
G1 X125 Y110 E0.333
G1 X115 Y110 E0.333
G1 X115 Y100 E0.333
;LAYER_CHANGE
;Z:0.4
;HEIGHT:0.2
G10 ; retract
G1 Z0.4 F720
G1 X100 Y100 F10800
G11 ; unretract
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X110 Y100 E0.333
G1 X110 Y110 E0.333
G1 X100 Y110 E0.333
G1 X100 Y100 E0.333
G10 ; retract
G1 X115 Y100 F10800
G11 ; unretract
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X125 Y100 E0.333
G1 X125 Y110 E0.333
G1 X115 Y110 E0.333
G1 X115 Y100 E0.333
;LAYER_CHANGE
;Z:0.6
;HEIGHT:0.2
G10 ; retract
G1 Z0.6 F720
G1 X100 Y100 F10800
G11 ; unretract
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X110 Y100 E0.333
G1 X110 Y110 E0.333
G1 X100 Y110 E0.333
G1 X100 Y100 E0.333
G10 ; retract
G1 X115 Y100 F10800
G11 ; unretract
;TYPE:External perimeter
;WIDTH:0.45
G1 F1200
G1 X125 Y100 E0.333
G1 X125 Y110 E0.333
G1 X115 Y110 E0.333
G1 X115 Y100 E0.333
G10 ; retract
G1 Z10.6 F720 ; move print head up
G1 X0 Y200 F3600 ; park
M107
M84 ; disable motors
; filament used [mm] = 7.99
