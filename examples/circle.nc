(circle.nc: a full circle of radius 10 mm, anticlockwise with G3, then the same)
(circle back clockwise with G2, at 3000 mm/min; centre at X10 Y0, start at the origin)
G21 G17 G90 G64
G3 X0 Y0 I10 J0 F3000  (full circle, centre 10 mm to the right: incremental I J)
G2 X0 Y0 I10 J0        (and back the other way)
G1 X2 Y0               (a short lead-out)
G1 X0 Y0
M2
