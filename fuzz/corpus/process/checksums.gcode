; poa sample: hand-written; host-protocol lines "N<n> <command>*<checksum>" (checksum = XOR of every byte before the *, as Marlin checks it; N0 M110 N0 resets the line counter), no comments after this header, 2 layers of a 10 mm square at (100,100), relative E (M83); Z only from the G1 Z moves
N0 M110 N0*125
N1 G21*27
N2 G90*18
N3 M83*27
N4 M107*33
N5 G1 Z0.2 F720*40
N6 G1 X100 Y100 F10800*112
N7 G1 F1200*74
N8 G1 X110 Y100 E0.333*104
N9 G1 X110 Y110 E0.333*104
N10 G1 X100 Y110 E0.333*81
N11 G1 X100 Y100 E0.333*81
N12 G1 E-0.8 F2100*16
N13 G1 Z0.4 F720*25
N14 G1 E0.8 F2100*59
N15 G1 F1200*121
N16 G1 X110 Y100 E0.333*87
N17 G1 X110 Y110 E0.333*87
N18 G1 X100 Y110 E0.333*89
N19 G1 X100 Y100 E0.333*89
N20 G1 E-0.8 F2100*17
N21 G1 Z10.6 F720*43
N22 M84*47
