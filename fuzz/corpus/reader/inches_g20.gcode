; poa sample: hand-written; G20 inch units: after G20 every X/Y/Z/E/F value is in inches (F in inch/min), 3 layers of 0.2 mm (Z0.007874 = 0.2 mm) each a 10 mm (0.3937 in) square at (100,100) mm = (3.93701,3.93701) in, E per side 0.01311 in (= 0.333 mm); ;Z:/;HEIGHT: tags and the footer are in mm as a slicer writes them; G21 switches back to mm before the end moves
G21 ; set units to millimeters
G90 ; use absolute coordinates
M83 ; use relative distances for extrusion
M107
G20 ; set units to inches
;LAYER_CHANGE
;Z:0.2
;HEIGHT:0.2
G1 Z0.007874 F28.35
G1 X3.937008 Y3.937008 F425.2
;TYPE:External perimeter
;WIDTH:0.45
G1 F47.24
G1 X4.330709 Y3.937008 E0.01311
G1 X4.330709 Y4.330709 E0.01311
G1 X3.937008 Y4.330709 E0.01311
G1 X3.937008 Y3.937008 E0.01311
;LAYER_CHANGE
;Z:0.4
;HEIGHT:0.2
G1 E-0.031496 F82.68 ; retract 0.8 mm
G1 Z0.015748 F28.35
G1 X3.937008 Y3.937008 F425.2
G1 E0.031496 F82.68 ; unretract
;TYPE:External perimeter
;WIDTH:0.45
G1 F47.24
G1 X4.330709 Y3.937008 E0.01311
G1 X4.330709 Y4.330709 E0.01311
G1 X3.937008 Y4.330709 E0.01311
G1 X3.937008 Y3.937008 E0.01311
;LAYER_CHANGE
;Z:0.6
;HEIGHT:0.2
G1 E-0.031496 F82.68 ; retract 0.8 mm
G1 Z0.023622 F28.35
G1 X3.937008 Y3.937008 F425.2
G1 E0.031496 F82.68 ; unretract
;TYPE:External perimeter
;WIDTH:0.45
G1 F47.24
G1 X4.330709 Y3.937008 E0.01311
G1 X4.330709 Y4.330709 E0.01311
G1 X3.937008 Y4.330709 E0.01311
G1 X3.937008 Y3.937008 E0.01311
G1 E-0.031496 F82.68 ; retract 0.8 mm
G21 ; back to millimeters
G1 Z10.6 F720 ; move print head up (mm)
G1 X0 Y200 F3600 ; park (mm)
M107
M84 ; disable motors
; filament used [mm] = 4.00
