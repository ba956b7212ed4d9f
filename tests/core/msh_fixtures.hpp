// Small MSH fixtures shared by the mesh tests (the gmsh path) and the direct-reader tests.
#pragma once

namespace bsms::test {

// A small MSH 2.2 file: two triangles, node 7 unused, node tags not contiguous.
// The line numbers in the reader tests' error messages refer to this text.
inline constexpr const char* kTwoTriangles = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
5
3 0 0 0
5 1 0 0
7 9 9 0
8 1 1 0
10 0 1 0
$EndNodes
$Elements
2
1 2 2 0 1 3 5 8
2 2 2 0 1 3 8 10
$EndElements
)";

}  // namespace bsms::test
