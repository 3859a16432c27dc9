(square.nc: a 20 mm square at 1500 mm/min, corners exact-stopped)
(start and end at the origin; every move is a feed move)
G21 G17 G90
G61                   (exact stop at every corner)
G1 X20 Y0 F1500
G1 X20 Y20
G1 X0 Y20
G1 X0 Y0
M2
