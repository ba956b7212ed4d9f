#include "core/mesh.hpp"

#include <gmsh.h>
#include <gtest/gtest.h>
#include <omp.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"
#include "core/graph.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

std::string temp_path(const std::string& name) {
  return (fs::temp_directory_path() / ("bsms_mesh_" + name)).string();
}

std::string write_text(const std::string& name, const std::string& text) {
  const std::string path = temp_path(name);
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& path) {
  try {
    read_mesh(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A small MSH 2.2 file: two triangles, node 7 unused, node tags not contiguous.
const char* kTwoTriangles = R"($MeshFormat
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

TEST(Mesh, NumbersNodesByAscendingTagAndDropsUnusedNodes) {
  const Mesh mesh = read_mesh(write_text("two.msh", kTwoTriangles));
  EXPECT_EQ(mesh.dim, 2);
  EXPECT_EQ(mesh.cell_dim, 2);
  ASSERT_EQ(mesh.num_nodes(), 4);
  EXPECT_EQ(mesh.node_tags, (std::vector<int64_t>{3, 5, 8, 10}));
  EXPECT_EQ(mesh.num_cells(), 2);
  EXPECT_EQ(mesh.cells(1, 0), 0);
  EXPECT_EQ(mesh.cells(1, 1), 2);
  EXPECT_EQ(mesh.cells(1, 2), 3);
  EXPECT_DOUBLE_EQ(mesh.points(2, 0), 1.0);
  EXPECT_DOUBLE_EQ(mesh.points(2, 1), 1.0);
}

TEST(Mesh, Msh22And41GiveTheSameMeshAndGroups) {
  const std::string v2 = temp_path("disk22.msh"), v4 = temp_path("disk41.msh");
  {
    GmshSession session;
    const int disk = gmsh::model::occ::addDisk(0, 0, 0, 1, 1);
    const int hole = gmsh::model::occ::addDisk(0.3, 0, 0, 0.2, 0.2);
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> map;
    gmsh::model::occ::cut({{2, disk}}, {{2, hole}}, out, map);
    gmsh::model::occ::synchronize();
    gmsh::vectorpair boundary;
    gmsh::model::getBoundary(out, boundary, true, false, false);
    std::vector<int> curves;
    for (const auto& [d, t] : boundary) curves.push_back(std::abs(t));
    gmsh::model::addPhysicalGroup(1, curves, 11);
    gmsh::model::setPhysicalName(1, 11, "wall");
    gmsh::model::addPhysicalGroup(2, {out[0].second}, 12);
    gmsh::option::setNumber("Mesh.CharacteristicLengthMax", 0.15);
    gmsh::model::mesh::generate(2);
    gmsh::option::setNumber("Mesh.MshFileVersion", 2.2);
    gmsh::write(v2);
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::write(v4);
  }
  const Mesh a = read_mesh(v2), b = read_mesh(v4);
  ASSERT_GT(a.num_nodes(), 50);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.cells, b.cells);
  EXPECT_EQ(a.node_tags, b.node_tags);
  ASSERT_EQ(a.node_groups.count("wall"), 1u);
  EXPECT_EQ(a.node_groups.at("wall"), b.node_groups.at("wall"));
  EXPECT_GT(a.node_groups.at("wall").size(), 10u);
  const CsrGraph ga = mesh_graph(a), gb = mesh_graph(b);
  EXPECT_EQ(ga.targets, gb.targets);
}

TEST(Mesh, ReadingKeepsTheOpenMpThreadCount) {
  omp_set_num_threads(2);
  read_mesh(write_text("threads.msh", kTwoTriangles));
  EXPECT_EQ(omp_get_max_threads(), 2);
}

TEST(Mesh, GeometryFilesAreMeshed) {
  const std::string geo = write_text("square.geo", R"(
Point(1) = {0, 0, 0, 0.2}; Point(2) = {1, 0, 0, 0.2}; Point(3) = {1, 1, 0, 0.2};
Point(4) = {0, 1, 0, 0.2};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
)");
  const Mesh mesh = read_mesh(geo);
  EXPECT_EQ(mesh.cell_dim, 2);
  EXPECT_GT(mesh.num_nodes(), 20);
}

TEST(Mesh, TetrahedraAndLines) {
  const std::string tet = write_text("tet.msh", R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
$EndNodes
$Elements
2
1 1 2 0 1 1 2
2 4 2 0 1 1 2 3 4
$EndElements
)");
  const Mesh m = read_mesh(tet);
  EXPECT_EQ(m.dim, 3);
  EXPECT_EQ(m.cell_dim, 3);
  EXPECT_EQ(m.num_cells(), 1);
  const std::string line = write_text("line.msh", R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
3
1 0 0 0
2 1 0 0
3 2 0 0
$EndNodes
$Elements
2
1 1 2 0 1 1 2
2 1 2 0 1 2 3
$EndElements
)");
  const Mesh l = read_mesh(line);
  EXPECT_EQ(l.dim, 1);
  EXPECT_EQ(l.cell_dim, 1);
  EXPECT_EQ(l.num_nodes(), 3);
}

TEST(Mesh, BadFilesGiveOneClearError) {
  EXPECT_NE(error_of(temp_path("nope.msh")).find("not found"), std::string::npos);
  EXPECT_NE(error_of(write_text("empty.msh", "")).find("empty"), std::string::npos);
  std::string truncated = kTwoTriangles;
  truncated.resize(truncated.size() / 2);
  const std::string cut = write_text("cut.msh", truncated);
  const std::string cut_error = error_of(cut);
  EXPECT_NE(cut_error.find(cut), std::string::npos) << cut_error;
  const std::string garbage = write_text("garbage.msh", "hello world\n");
  EXPECT_NE(error_of(garbage).find(garbage), std::string::npos);
  std::string nan_mesh = kTwoTriangles;
  nan_mesh.replace(nan_mesh.find("8 1 1 0"), 7, "8 nan 1 0");
  const std::string nan_error = error_of(write_text("nan.msh", nan_mesh));
  EXPECT_NE(nan_error.find("non-finite"), std::string::npos) << nan_error;
  const std::string mixed = write_text("mixed.msh", R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
5
1 0 0 0
2 1 0 0
3 1 1 0
4 0 1 0
5 2 0 0
$EndNodes
$Elements
2
1 3 2 0 1 1 2 3 4
2 2 2 0 1 2 5 3
$EndElements
)");
  const std::string mixed_error = error_of(mixed);
  EXPECT_NE(mixed_error.find("mixed"), std::string::npos) << mixed_error;
  const std::string points_only = write_text("points.msh", R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
1
1 0 0 0
$EndNodes
$Elements
1
1 15 2 0 1 1
$EndElements
)");
  EXPECT_NE(error_of(points_only).find("empty mesh"), std::string::npos);
}

TEST(Mesh, MakeMeshValidates) {
  RowMatrixXd p(3, 2);
  p << 0, 0, 1, 0, 0, 1;
  RowMatrixXi64 c(1, 3);
  c << 0, 1, 3;
  EXPECT_THROW(make_mesh(2, p, c), InputError);
  c << 0, 1, 1;
  EXPECT_THROW(make_mesh(2, p, c), InputError);
  c << 0, 1, 2;
  p(1, 1) = std::nan("");
  EXPECT_THROW(make_mesh(2, p, c), InputError);
}

// Bad cells: brute-force cases with known answers, clean gmsh meshes in both orientations.
TEST(Mesh, FindBadCellsNamesZeroAreaAndInvertedCells) {
  RowMatrixXd p(5, 2);
  p << 0, 0, 1, 0, 1, 1, 0, 1, 2, 2;
  RowMatrixXi64 c(3, 3);
  c << 0, 1, 2, 0, 2, 3, 0, 2, 4;  // cell 2: collinear (0,0), (1,1), (2,2)
  BadCells bad = find_bad_cells(make_mesh(2, p, c));
  EXPECT_EQ(bad.degenerate, 1);
  EXPECT_EQ(bad.inverted, 0);
  EXPECT_EQ(bad.first, 2);
  EXPECT_EQ(bad.describe(),
            "1 bad cell (1 zero-measure, 0 inverted), first: cell 2 (zero-measure)");

  // Fold: vertex 3 moved across the diagonal 0-2, onto the side of cell 0.
  RowMatrixXd q(5, 2);
  q << 0, 0, 1, 0, 1, 1, 1.5, 0.5, 0, 1;
  RowMatrixXi64 f(3, 3);
  f << 0, 1, 2, 0, 2, 3, 0, 2, 4;  // cell 0 and 2 positive, cell 1 folded over cell 0
  bad = find_bad_cells(make_mesh(2, q, f));
  EXPECT_EQ(bad.degenerate, 0);
  EXPECT_EQ(bad.inverted, 1);
  EXPECT_EQ(bad.first, 1);
  EXPECT_EQ(bad.first_kind, "inverted");

  // The same meshes without the bad cell are clean, whatever their orientation.
  RowMatrixXi64 good(2, 3);
  good << 0, 1, 2, 0, 2, 4;
  EXPECT_EQ(find_bad_cells(make_mesh(2, q, good)).count(), 0);
  good << 0, 2, 1, 0, 4, 2;  // clockwise
  EXPECT_EQ(find_bad_cells(make_mesh(2, q, good)).count(), 0);

  // A flat tetrahedron and a triangle of zero area in 3D (Gram determinant).
  RowMatrixXd t(4, 3);
  t << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0;
  RowMatrixXi64 tet(1, 4);
  tet << 0, 1, 2, 3;
  EXPECT_EQ(find_bad_cells(make_mesh(3, t, tet)).degenerate, 1);
  RowMatrixXi64 tri(2, 3);
  tri << 0, 1, 2, 1, 2, 3;
  EXPECT_EQ(find_bad_cells(make_mesh(3, t, tri)).count(), 0);
  t.row(3) << 2, 0, 0;  // (0,0,0), (1,0,0), (2,0,0): a zero-area triangle in 3D
  tri << 0, 1, 3, 0, 1, 2;
  EXPECT_EQ(find_bad_cells(make_mesh(3, t, tri)).degenerate, 1);
}

TEST(Mesh, GmshMeshesHaveNoBadCells) {
  for (const std::string& geo :
       {std::string("SetFactory(\"OpenCASCADE\");\nRectangle(1) = {0, 0, 0, 1, 1};\n"
                    "Mesh.MeshSizeMax = 0.1;\n"),
        std::string("SetFactory(\"OpenCASCADE\");\nBox(1) = {0, 0, 0, 1, 1, 1};\n"
                    "Mesh.MeshSizeMax = 0.25;\n")}) {
    const Mesh mesh = read_mesh(write_text("clean.geo", geo));
    const BadCells bad = find_bad_cells(mesh);
    EXPECT_EQ(bad.count(), 0) << bad.describe();
    EXPECT_GT(mesh.num_cells(), 50);
  }
}

// A collinear triangle reads without error (preprocess warns, the solver refuses).
TEST(Mesh, CollinearTriangleIsReadAndFound) {
  const std::string path = write_text("collinear.msh", R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
5
1 0 0 0
2 1 0 0
3 1 1 0
4 0 1 0
5 2 2 0
$EndNodes
$Elements
3
1 2 2 0 1 1 2 3
2 2 2 0 1 1 3 4
3 2 2 0 1 1 3 5
$EndElements
)");
  const Mesh mesh = read_mesh(path);
  const BadCells bad = find_bad_cells(mesh);
  EXPECT_EQ(bad.degenerate, 1);
  EXPECT_EQ(bad.first, 2);
}

// A geometry whose element size is a unit typo is refused before meshing, with the estimate.
TEST(Mesh, HugeGeometryIsRefusedBeforeMeshing) {
  const std::string path =
      write_text("huge.geo",
                 "SetFactory(\"OpenCASCADE\");\nRectangle(1) = {0, 0, 0, 1, 1};\n"
                 "Mesh.MeshSizeMax = 1e-5;\nMesh.MeshSizeMin = 1e-5;\n");
  const auto start = std::chrono::steady_clock::now();
  const std::string error = error_of(path);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find("would mesh to about 1.2e+10 nodes"), std::string::npos) << error;
  EXPECT_NE(error.find("limit 5e+07"), std::string::npos) << error;
  EXPECT_LT(seconds, 10.0);
}

}  // namespace
}  // namespace bsms
