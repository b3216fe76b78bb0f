( circle.gcode: circles from G02/G03 arcs, both forms )
G18 G21 G90
( 1: a full circle of radius 50 mm around X125 Z125, from its left point, I/K centre offsets )
N10 G00 X75 Z125 Y0
N20 Y1
N30 G02 X75 Z125 I50 K0
N40 Y0
( 2: the same size circle as two half circles with R, counter-clockwise )
N50 G00 X30 Z60
N60 Y1
N70 G03 X130 Z60 R50   ; lower half, left to right
N80 G03 X30 Z60 R50    ; upper half, back
N90 Y0
( 3: a long arc: negative R takes the way round that is longer than 180 degrees )
N100 G00 X200 Z30
N110 Y1
N120 G02 X200 Z90 R-40
N130 Y0
N140 G00 X0 Z0
