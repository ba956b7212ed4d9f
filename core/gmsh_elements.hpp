// gmsh's element types (gmsh 4.8), shared by the mesh assembly and the direct MSH reader.
#pragma once

#include <string>

namespace bsms {

// A gmsh element type as gmsh 4.8 defines it.
struct GmshElementType {
  int type;
  int dim;        // topological dimension (0 point .. 3 volume)
  int num_nodes;  // 0 for variable-size types (polygons, polyhedra, xfem)
  const char* name;
};
// nullptr when gmsh 4.8 defines no such type.
const GmshElementType* gmsh_element_type(int type);
// gmsh's name of the type ("Triangle 6"), or "gmsh element type N".
std::string gmsh_element_name(int type);

// gmsh's element type code of the simplex of topological dimension `cell_dim` (1: 2-node line,
// 2: 3-node triangle, 3: 4-node tetrahedron); -1 for any other dimension.
int gmsh_simplex_type(int cell_dim);

}  // namespace bsms
