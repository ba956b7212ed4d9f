#include "msh_fixtures.hpp"

#include <gmsh.h>
#include <gtest/gtest.h>

#include <omp.h>
#include <Eigen/Dense>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"
#include "core/graph.hpp"
#include "msh_fixtures.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;
using test::kTwoTriangles;

// A file in this test process's own folder.
std::string temp_path(const std::string& name) {
  static const fs::path dir = bsms::testing::unique_temp_dir("mesh");
  return (dir / name).string();
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

// find_bad_cells against a plain statement of its rule (faces grouped in a std::map, Eigen
// determinants) on jittered 2D and 3D grids with folded and collapsed cells.
TEST(Mesh, FindBadCellsEqualsBruteForceOnRandomMeshes) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int64_t total_inverted = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const int dim = trial % 2 == 0 ? 2 : 3;
    const int n = dim == 2 ? 9 : 4;
    const int side = n + 1;
    const int64_t nodes = dim == 2 ? side * side : side * side * side;
    RowMatrixXd p(nodes, dim);
    for (int64_t v = 0; v < nodes; ++v) {
      int64_t rest = v;
      for (int i = 0; i < dim; ++i) {
        p(v, i) = static_cast<double>(rest % side) + 0.3 * (unit(rng) - 0.5);
        rest /= side;
      }
    }
    // Move a few nodes far (folds) and collapse a few onto a neighbour (zero measure).
    for (int m = 0; m < 3; ++m) {
      const int64_t v = static_cast<int64_t>(unit(rng) * nodes);
      for (int i = 0; i < dim; ++i) p(v, i) += 1.6 * (unit(rng) - 0.5);
    }
    std::vector<std::array<int64_t, 4>> cells;
    auto id = [&](int x, int y, int z) { return x + side * (y + side * z); };
    if (dim == 2) {
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
          cells.push_back({id(x, y, 0), id(x + 1, y, 0), id(x + 1, y + 1, 0), -1});
          cells.push_back({id(x, y, 0), id(x + 1, y + 1, 0), id(x, y + 1, 0), -1});
        }
    } else {
      for (int z = 0; z < n; ++z)
        for (int y = 0; y < n; ++y)
          for (int x = 0; x < n; ++x) {
            const int64_t c0 = id(x, y, z), c1 = id(x + 1, y, z), c2 = id(x + 1, y + 1, z),
                          c3 = id(x, y + 1, z), c4 = id(x, y, z + 1), c5 = id(x + 1, y, z + 1),
                          c6 = id(x + 1, y + 1, z + 1), c7 = id(x, y + 1, z + 1);
            for (const auto& t : std::vector<std::array<int64_t, 4>>{{c0, c1, c2, c6},
                                                                     {c0, c2, c3, c6},
                                                                     {c0, c3, c7, c6},
                                                                     {c0, c7, c4, c6},
                                                                     {c0, c4, c5, c6},
                                                                     {c0, c5, c1, c6}})
              cells.push_back(t);
          }
    }
    const int k = dim + 1;
    RowMatrixXi64 c(static_cast<int64_t>(cells.size()), k);
    for (size_t i = 0; i < cells.size(); ++i)
      for (int a = 0; a < k; ++a) c(i, a) = cells[i][a];
    // Collapse: a cell's vertex placed on another of its vertices.
    const int64_t flat = static_cast<int64_t>(unit(rng) * c.rows());
    p.row(c(flat, 1)) = p.row(c(flat, 0));
    const Mesh mesh = make_mesh(dim, p, c);
    // Brute force.
    const int64_t C = c.rows();
    std::vector<double> measure(C);
    std::vector<int> kind(C, 0);
    int64_t positive = 0, degenerate = 0;
    for (int64_t i = 0; i < C; ++i) {
      Eigen::MatrixXd jac(dim, dim);
      double longest = 0.0;
      for (int a = 0; a < k; ++a)
        for (int b = a + 1; b < k; ++b)
          longest = std::max(longest, (p.row(c(i, a)) - p.row(c(i, b))).norm());
      for (int a = 0; a < dim; ++a) jac.col(a) = (p.row(c(i, a + 1)) - p.row(c(i, 0))).transpose();
      measure[i] = longest > 0 ? jac.determinant() / std::pow(longest, dim) : 0.0;
      if (!(std::abs(measure[i]) > 1e-10)) {
        kind[i] = 1;
        ++degenerate;
      } else if (measure[i] > 0) {
        ++positive;
      }
    }
    const double majority = 2 * positive >= C - degenerate ? 1.0 : -1.0;
    std::map<std::vector<int64_t>, std::vector<std::pair<int64_t, int64_t>>> faces;
    for (int64_t i = 0; i < C; ++i) {
      if (kind[i]) continue;
      for (int skip = 0; skip < k; ++skip) {
        std::vector<int64_t> key;
        for (int a = 0; a < k; ++a)
          if (a != skip) key.push_back(c(i, a));
        std::sort(key.begin(), key.end());
        faces[key].push_back({i, c(i, skip)});
      }
    }
    int64_t inverted = 0;
    for (const auto& [key, list] : faces) {
      auto side = [&](int64_t v) {
        Eigen::MatrixXd m(dim, dim);
        for (int a = 1; a < dim; ++a) m.col(a - 1) = (p.row(key[a]) - p.row(key[0])).transpose();
        m.col(dim - 1) = (p.row(v) - p.row(key[0])).transpose();
        return m.determinant();
      };
      for (size_t j = 0; j + 1 < list.size(); ++j) {
        if (!(side(list[j].second) * side(list[j + 1].second) > 0.0)) continue;
        for (int64_t cell : {list[j].first, list[j + 1].first})
          if (kind[cell] == 0 && measure[cell] * majority < 0.0) {
            kind[cell] = 2;
            ++inverted;
          }
      }
    }
    const BadCells bad = find_bad_cells(mesh);
    SCOPED_TRACE("trial " + std::to_string(trial));
    EXPECT_EQ(bad.degenerate, degenerate);
    EXPECT_EQ(bad.inverted, inverted);
    EXPECT_GE(bad.count(), 1);  // the collapsed cell at least
    const auto first = std::find_if(kind.begin(), kind.end(), [](int x) { return x != 0; });
    EXPECT_EQ(bad.first, first - kind.begin());
    total_inverted += inverted;
  }
  EXPECT_GT(total_inverted, 5);  // folds occur, so both kinds are compared
}

}  // namespace
}  // namespace bsms
