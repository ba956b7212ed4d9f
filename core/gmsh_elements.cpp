#include "core/gmsh_elements.hpp"

#include <array>

namespace bsms {
namespace {

// Element types of gmsh 4.8 (gmsh::model::mesh::getElementProperties for types 1..200).
// A constant data table, one row per type (long by nature, no logic).
constexpr GmshElementType kElementTypes[] = {
    {1, 1, 2, "Line 2"},
    {2, 2, 3, "Triangle 3"},
    {3, 2, 4, "Quadrilateral 4"},
    {4, 3, 4, "Tetrahedron 4"},
    {5, 3, 8, "Hexahedron 8"},
    {6, 3, 6, "Prism 6"},
    {7, 3, 5, "Pyramid 5"},
    {8, 1, 3, "Line 3"},
    {9, 2, 6, "Triangle 6"},
    {10, 2, 9, "Quadrilateral 9"},
    {11, 3, 10, "Tetrahedron 10"},
    {12, 3, 27, "Hexahedron 27"},
    {13, 3, 18, "Prism 18"},
    {14, 3, 14, "Pyramid 14"},
    {15, 0, 1, "Point"},
    {16, 2, 8, "Quadrilateral 8"},
    {17, 3, 20, "Hexahedron 20"},
    {18, 3, 15, "Prism 15"},
    {19, 3, 13, "Pyramid 13"},
    {20, 2, 9, "Triangle 9"},
    {21, 2, 10, "Triangle 10"},
    {22, 2, 12, "Triangle 12"},
    {23, 2, 15, "Triangle 15"},
    {24, 2, 15, "Triangle 15I"},
    {25, 2, 21, "Triangle 21"},
    {26, 1, 4, "Line 4"},
    {27, 1, 5, "Line 5"},
    {28, 1, 6, "Line 6"},
    {29, 3, 20, "Tetrahedron 20"},
    {30, 3, 35, "Tetrahedron 35"},
    {31, 3, 56, "Tetrahedron 56"},
    {32, 3, 22, "Tetrahedron 22"},
    {33, 3, 28, "Tetrahedron 28"},
    {34, 2, 0, "Polygon"},
    {35, 3, 0, "Polyhedron"},
    {36, 2, 16, "Quadrilateral 16"},
    {37, 2, 25, "Quadrilateral 25"},
    {38, 2, 36, "Quadrilateral 36"},
    {39, 2, 12, "Quadrilateral 12"},
    {40, 2, 16, "Quadrilateral 16I"},
    {41, 2, 20, "Quadrilateral 20"},
    {42, 2, 28, "Triangle 28"},
    {43, 2, 36, "Triangle 36"},
    {44, 2, 45, "Triangle 45"},
    {45, 2, 55, "Triangle 55"},
    {46, 2, 66, "Triangle 66"},
    {47, 2, 49, "Quadrilateral 49"},
    {48, 2, 64, "Quadrilateral 64"},
    {49, 2, 81, "Quadrilateral 81"},
    {50, 2, 100, "Quadrilateral 100"},
    {51, 2, 121, "Quadrilateral 121"},
    {52, 2, 18, "Triangle 18"},
    {53, 2, 21, "Triangle 21I"},
    {54, 2, 24, "Triangle 24"},
    {55, 2, 27, "Triangle 27"},
    {56, 2, 30, "Triangle 30"},
    {57, 2, 24, "Quadrilateral 24"},
    {58, 2, 28, "Quadrilateral 28"},
    {59, 2, 32, "Quadrilateral 32"},
    {60, 2, 36, "Quadrilateral 36I"},
    {61, 2, 40, "Quadrilateral 40"},
    {62, 1, 7, "Line 7"},
    {63, 1, 8, "Line 8"},
    {64, 1, 9, "Line 9"},
    {65, 1, 10, "Line 10"},
    {66, 1, 11, "Line 11"},
    {69, 2, 0, "Polygon Border"},
    {71, 3, 84, "Tetrahedron 84"},
    {72, 3, 120, "Tetrahedron 120"},
    {73, 3, 165, "Tetrahedron 165"},
    {74, 3, 220, "Tetrahedron 220"},
    {75, 3, 286, "Tetrahedron 286"},
    {79, 3, 34, "Tetrahedron 34"},
    {80, 3, 40, "Tetrahedron 40"},
    {81, 3, 46, "Tetrahedron 46"},
    {82, 3, 52, "Tetrahedron 52"},
    {83, 3, 58, "Tetrahedron 58"},
    {84, 1, 1, "Line 1"},
    {85, 2, 1, "Triangle 1"},
    {86, 2, 1, "Quadrilateral 1"},
    {87, 3, 1, "Tetrahedron 1"},
    {88, 3, 1, "Hexahedron 1"},
    {89, 3, 1, "Prism 1"},
    {92, 3, 64, "Hexahedron 64"},
    {93, 3, 125, "Hexahedron 125"},
    {94, 3, 216, "Hexahedron 216"},
    {95, 3, 343, "Hexahedron 343"},
    {96, 3, 512, "Hexahedron 512"},
    {97, 3, 729, "Hexahedron 729"},
    {98, 3, 1000, "Hexahedron 1000"},
    {99, 3, 32, "Hexahedron 32"},
    {100, 3, 44, "Hexahedron 44"},
    {101, 3, 56, "Hexahedron 56"},
    {102, 3, 68, "Hexahedron 68"},
    {103, 3, 80, "Hexahedron 80"},
    {104, 3, 92, "Hexahedron 92"},
    {105, 3, 104, "Hexahedron 104"},
    {118, 3, 30, "Pyramid 30"},
    {119, 3, 55, "Pyramid 55"},
    {120, 3, 91, "Pyramid 91"},
    {121, 3, 140, "Pyramid 140"},
    {122, 3, 204, "Pyramid 204"},
    {123, 3, 285, "Pyramid 285"},
    {124, 3, 385, "Pyramid 385"},
    {125, 3, 21, "Pyramid 21"},
    {126, 3, 29, "Pyramid 29"},
    {127, 3, 37, "Pyramid 37"},
    {128, 3, 45, "Pyramid 45"},
    {129, 3, 53, "Pyramid 53"},
    {130, 3, 61, "Pyramid 61"},
    {131, 3, 69, "Pyramid 69"},
    {132, 3, 1, "Pyramid 1"},
    {133, 0, 0, "Point Xfem"},
    {134, 1, 0, "Line Xfem"},
    {135, 2, 0, "Triangle Xfem"},
    {136, 3, 0, "Tetrahedron Xfem"},
    {137, 3, 16, "Tetrahedron 16"},
};

constexpr int kMaxElementType = 137;

}  // namespace

const GmshElementType* gmsh_element_type(int type) {
  static const std::array<const GmshElementType*, kMaxElementType + 1> by_type = [] {
    std::array<const GmshElementType*, kMaxElementType + 1> table{};
    for (const GmshElementType& t : kElementTypes) table[t.type] = &t;
    return table;
  }();
  return type >= 0 && type <= kMaxElementType ? by_type[type] : nullptr;
}

std::string gmsh_element_name(int type) {
  const GmshElementType* t = gmsh_element_type(type);
  return t ? std::string(t->name) : "gmsh element type " + std::to_string(type);
}

// gmsh element type codes of the simplices bsms accepts, by topological dimension.
constexpr int kGmshLine2 = 1, kGmshTriangle3 = 2, kGmshTetrahedron4 = 4;

int gmsh_simplex_type(int cell_dim) {
  switch (cell_dim) {
    case 1:
      return kGmshLine2;
    case 2:
      return kGmshTriangle3;
    case 3:
      return kGmshTetrahedron4;
    default:
      return -1;
  }
}

}  // namespace bsms
