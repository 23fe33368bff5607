MeshVersionFormatted 2
Dimension 3
SolAtVertices
2
2 1 3
0.5 1 0 1 0 0 1
0.25 2 0 2 0 0 2
End
