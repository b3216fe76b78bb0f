G21 G90 (pierce delays: the torch lights and stands still before each cut)
G00 X10 Y10
G04 P0.5
G01 X40 Y10 F600
G01 X40 Y30
G04 P0.2 (a pause inside the contour: the torch stays lit)
G01 X10 Y30
G01 X10 Y10
G00 X60 Y20
G04 P0.5
G02 X60 Y20 I5 J0
G00 X0 Y0
