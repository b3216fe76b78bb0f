n1 g01 x2 z2 y0, n2 y1, n3 x12 z2, n4 x12 z10, n5 x2 z10, n6 x2 z2,
n7 x12 z10, n8 x7 z15, n9 x2 z10, n10 x12 z2,
n11 y0, n12 x15 z5, n13 y1, n14 g03 x21 z5 r3, n15 g03 x15 z5 r3, n16 y0, n17 g01 x0 z0
