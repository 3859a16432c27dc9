(pocket.nc: a small rectangular pocket, 1 mm deep: rings of 4 x 2, 8 x 6 and 12 x 8 mm)
(cleared from the centre outwards; corners blended: G64)
G21 G17 G90 G64
G1 Z-1 F300           (plunge at the centre, X0 Y0)
F1200
G91                   (incremental moves: each ring is drawn from its lower left corner)
G1 X-2 Y-1
G1 X4
G1 Y2
G1 X-4
G1 Y-2
G1 X-2 Y-2            (second ring: 8 x 6 mm)
G1 X8
G1 Y6
G1 X-8
G1 Y-6
G1 X-2 Y-1            (last ring: 12 x 8 mm)
G1 X12
G1 Y8
G1 X-12
G1 Y-8
G90
G1 X0 Y0              (back to the centre)
G1 Z0 F300            (retract)
M2
