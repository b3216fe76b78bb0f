( star.gcode: a five-pointed star turned 18 degrees so one edge is vertical; )
( the others are steep, at 54 and 126 degrees, or shallow; then a pen-up travel )
( to a vertical line and a steep line. Units: cm, the seed's drawing units. )
G18 G90
N10 G00 X8.219 Z20.560 Y0
N20 Y1
N30 G01 X8.219 Z3.440
N40 G01 X18.281 Z17.290
N50 G01 X2.000 Z12.000
N60 G01 X18.281 Z6.710
N70 G01 X8.219 Z20.560
N80 Y0
N90 G00 X22 Z2     ( pen-up travel )
N100 Y1
N110 G01 Z10        ( vertical edge: DX = 0 )
N120 X22.5 Z20      ( steep edge: 20 steps of Z per step of X )
N130 Y0
N140 G00 X0 Z0
