( square.gcode: a 10 cm square on the seed table )
( plane X-Z as on the table; Y1 lowers the pen, Y0 lifts it )
G18 G21 G90          ; X-Z plane, millimetres, absolute
N10 G00 X50 Z50 Y0   ; pen-up travel to the first corner
N20 Y1               ; pen down
N30 G01 X150 F300
N40 Z150
N50 X50
N60 Z50
N70 Y0               ; pen up
N80 G00 X0 Z0        ; back home
