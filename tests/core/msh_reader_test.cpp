// The direct MSH reader against the gmsh library: meshes written by gmsh itself in MSH 2.2 and
// 4.1, ASCII and binary, read both ways must give exactly the same Mesh; bad input must give one
// InputError naming the file and the place.
#include "core/msh_reader.hpp"

#include <gmsh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"
#include "core/mesh.hpp"
#include "msh_fixtures.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

// One folder per test process, removed when it ends: ctest runs the tests of this file as
// parallel processes, and several of them write the same file names (the plate in every format).
const fs::path& temp_dir() {
  static const struct Dir {
    fs::path path = bsms::testing::unique_temp_dir("msh");
    ~Dir() {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  } dir;
  return dir.path;
}

std::string temp_path(const std::string& name) {
  return (temp_dir() / name).string();
}

std::string write_bytes(const std::string& name, const std::string& bytes) {
  const std::string path = temp_path(name);
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

template <class Read>
std::string error_of(Read read, const std::string& path) {
  try {
    read(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}
std::string direct_error(const std::string& path) {
  return error_of([](const std::string& p) { return read_msh(p); }, path);
}

// Points bitwise, cells, tags and groups exactly.
void expect_same_mesh(const Mesh& a, const Mesh& b, const std::string& what) {
  EXPECT_EQ(a.dim, b.dim) << what;
  EXPECT_EQ(a.cell_dim, b.cell_dim) << what;
  ASSERT_EQ(a.points.rows(), b.points.rows()) << what;
  ASSERT_EQ(a.points.cols(), b.points.cols()) << what;
  EXPECT_EQ(std::memcmp(a.points.data(), b.points.data(), sizeof(double) * a.points.size()), 0)
      << what;
  EXPECT_EQ(a.cells, b.cells) << what;
  EXPECT_EQ(a.node_tags, b.node_tags) << what;
  EXPECT_EQ(a.node_groups, b.node_groups) << what;
}

// The current gmsh model written as MSH 2.2 / 4.1, ASCII / binary (and 4.1 with parametric
// coordinates): the paths. gmsh's options are global, so they are put back to the defaults.
std::vector<std::string> write_all_formats(const std::string& name) {
  std::vector<std::string> paths;
  struct Format {
    double version;
    int binary;
    int parametric;
    const char* suffix;
  };
  for (const Format& f :
       {Format{2.2, 0, 0, "22"}, Format{2.2, 1, 0, "22b"}, Format{4.1, 0, 0, "41"},
        Format{4.1, 1, 0, "41b"}, Format{4.1, 0, 1, "41p"}, Format{4.1, 1, 1, "41pb"}}) {
    gmsh::option::setNumber("Mesh.MshFileVersion", f.version);
    gmsh::option::setNumber("Mesh.Binary", f.binary);
    gmsh::option::setNumber("Mesh.SaveParametric", f.parametric);
    paths.push_back(temp_path(name + "_" + f.suffix + ".msh"));
    gmsh::write(paths.back());
  }
  gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
  gmsh::option::setNumber("Mesh.Binary", 0);
  gmsh::option::setNumber("Mesh.SaveParametric", 0);
  return paths;
}

// Reads every file directly (read_msh and the read_mesh dispatch) and through gmsh.
std::vector<Mesh> expect_direct_equals_gmsh(const std::vector<std::string>& paths) {
  std::vector<Mesh> meshes;
  for (const std::string& path : paths) {
    EXPECT_TRUE(is_direct_msh(read_bytes(path).substr(0, 4096))) << path;
    const Mesh direct = read_msh(path);
    const Mesh gmsh_mesh = read_mesh_with_gmsh(path);
    expect_same_mesh(direct, gmsh_mesh, path);
    expect_same_mesh(read_mesh(path), gmsh_mesh, path + " (read_mesh)");
    meshes.push_back(direct);
  }
  return meshes;
}

// A 2 x 1 plate with two holes: groups of every dimension, the surface in two of them (gmsh's
// MSH 2.2 writer then repeats its triangles), an unnamed corner point.
std::vector<std::string> plate_with_holes_files() {
  static std::vector<std::string> paths;
  if (!paths.empty()) return paths;
  GmshSession session;
  const int plate = gmsh::model::occ::addRectangle(0, 0, 0, 2, 1);
  const int hole1 = gmsh::model::occ::addDisk(0.5, 0.5, 0, 0.2, 0.2);
  const int hole2 = gmsh::model::occ::addDisk(1.4, 0.4, 0, 0.15, 0.15);
  gmsh::vectorpair out;
  std::vector<gmsh::vectorpair> map;
  gmsh::model::occ::cut({{2, plate}}, {{2, hole1}, {2, hole2}}, out, map);
  gmsh::model::occ::synchronize();
  gmsh::vectorpair curves;
  gmsh::model::getBoundary(out, curves, false, false, false);
  std::vector<int> outer, holes;
  for (const auto& [d, t] : curves) {
    double box[6];
    gmsh::model::getBoundingBox(1, std::abs(t), box[0], box[1], box[2], box[3], box[4], box[5]);
    const bool on_edge = box[0] < 1e-6 || box[3] > 2 - 1e-6 || box[1] < 1e-6 || box[4] > 1 - 1e-6;
    (on_edge ? outer : holes).push_back(std::abs(t));
  }
  gmsh::model::setPhysicalName(2, gmsh::model::addPhysicalGroup(2, {out[0].second}), "plate");
  gmsh::model::setPhysicalName(2, gmsh::model::addPhysicalGroup(2, {out[0].second}), "all");
  gmsh::model::setPhysicalName(1, gmsh::model::addPhysicalGroup(1, outer), "outer");
  gmsh::model::setPhysicalName(1, gmsh::model::addPhysicalGroup(1, holes), "holes");
  gmsh::vectorpair points;
  gmsh::model::getEntities(points, 0);
  gmsh::model::addPhysicalGroup(0, {points[0].second}, 40);
  gmsh::option::setNumber("Mesh.MeshSizeMax", 0.08);
  gmsh::model::mesh::generate(2);
  paths = write_all_formats("plate");
  return paths;
}

TEST(MshReader, PlateWithHolesEqualsTheGmshPath) {
  const std::vector<Mesh> meshes = expect_direct_equals_gmsh(plate_with_holes_files());
  const Mesh& m = meshes.front();
  EXPECT_EQ(m.dim, 2);
  EXPECT_GT(m.num_nodes(), 300);
  EXPECT_EQ(m.node_groups.at("plate").size(), static_cast<size_t>(m.num_nodes()));
  EXPECT_EQ(m.node_groups.at("all"), m.node_groups.at("plate"));
  EXPECT_GT(m.node_groups.at("holes").size(), 20u);
  EXPECT_GT(m.node_groups.at("outer").size(), 50u);
  EXPECT_EQ(m.node_groups.at("0:40").size(), 1u);
  // MSH 2.2 repeats the triangles of a surface in two groups, and gmsh keeps both copies.
  EXPECT_EQ(meshes[0].num_cells(), 2 * meshes[2].num_cells());
}

TEST(MshReader, TetrahedralBoxEqualsTheGmshPath) {
  std::vector<std::string> paths;
  {
    GmshSession session;
    const int box = gmsh::model::occ::addBox(0, 0, 0, 1, 0.5, 0.7);
    gmsh::model::occ::synchronize();
    gmsh::vectorpair faces;
    gmsh::model::getBoundary({{3, box}}, faces, false, false, false);
    std::vector<int> bottom, sides;
    for (const auto& [d, t] : faces) {
      double b[6];
      gmsh::model::getBoundingBox(2, std::abs(t), b[0], b[1], b[2], b[3], b[4], b[5]);
      (b[5] < 1e-6 ? bottom : sides).push_back(std::abs(t));
    }
    gmsh::model::setPhysicalName(3, gmsh::model::addPhysicalGroup(3, {box}, 1), "solid");
    gmsh::model::setPhysicalName(2, gmsh::model::addPhysicalGroup(2, bottom, 2), "bottom");
    gmsh::model::setPhysicalName(2, gmsh::model::addPhysicalGroup(2, sides, 3), "sides");
    gmsh::model::addPhysicalGroup(1, {1, 2}, 4);
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.15);
    gmsh::model::mesh::generate(3);
    paths = write_all_formats("box");
  }
  const std::vector<Mesh> meshes = expect_direct_equals_gmsh(paths);
  const Mesh& m = meshes.front();
  EXPECT_EQ(m.dim, 3);
  EXPECT_EQ(m.cell_dim, 3);
  EXPECT_GT(m.num_cells(), 300);
  EXPECT_GT(m.node_groups.at("bottom").size(), 10u);
  EXPECT_GT(m.node_groups.at("sides").size(), m.node_groups.at("bottom").size());
  EXPECT_GT(m.node_groups.at("1:4").size(), 5u);
}

TEST(MshReader, LineMeshesEqualTheGmshPath) {
  std::vector<std::string> straight, circle;
  {
    GmshSession session;
    const int a = gmsh::model::occ::addPoint(0, 0, 0), b = gmsh::model::occ::addPoint(1, 0, 0);
    const int c = gmsh::model::occ::addPoint(3, 0, 0);
    const int l1 = gmsh::model::occ::addLine(a, b), l2 = gmsh::model::occ::addLine(b, c);
    gmsh::model::occ::synchronize();
    gmsh::model::setPhysicalName(1, gmsh::model::addPhysicalGroup(1, {l1, l2}), "wire");
    gmsh::model::setPhysicalName(0, gmsh::model::addPhysicalGroup(0, {a, c}), "ends");
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.1);
    gmsh::model::mesh::generate(1);
    straight = write_all_formats("wire");
  }
  {
    GmshSession session;
    gmsh::model::occ::addCircle(0, 0, 0, 1);
    gmsh::model::occ::synchronize();
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.1);
    gmsh::model::mesh::generate(1);
    circle = write_all_formats("circle");
  }
  const Mesh wire = expect_direct_equals_gmsh(straight).front();
  EXPECT_EQ(wire.dim, 1);
  EXPECT_EQ(wire.cell_dim, 1);
  EXPECT_EQ(wire.node_groups.at("ends").size(), 2u);
  const Mesh ring = expect_direct_equals_gmsh(circle).front();
  EXPECT_EQ(ring.dim, 2);
  EXPECT_EQ(ring.cell_dim, 1);
  EXPECT_GT(ring.num_cells(), 50);
}

// Node tags far from 1..N (the hash path): a gmsh model built from arrays with tags 7t + 1000,
// written by gmsh, and hand-written files with tags in any order.
TEST(MshReader, SparseNodeTagsEqualTheGmshPath) {
  std::vector<std::string> paths;
  {
    GmshSession session;
    gmsh::model::occ::addRectangle(0, 0, 0, 1, 1);
    gmsh::model::occ::synchronize();
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.1);
    gmsh::model::mesh::generate(2);
    std::vector<std::size_t> tags, element_tags, element_nodes;
    std::vector<double> coords, parametric;
    gmsh::model::mesh::getNodes(tags, coords, parametric);
    gmsh::model::mesh::getElementsByType(2, element_tags, element_nodes);
    for (std::size_t& t : tags) t = 7 * t + 1000;
    for (std::size_t& t : element_nodes) t = 7 * t + 1000;
    gmsh::model::add("sparse");
    gmsh::model::addDiscreteEntity(2, 5);
    gmsh::model::mesh::addNodes(2, 5, tags, coords);
    gmsh::model::mesh::addElementsByType(5, 2, {}, element_nodes);
    paths = write_all_formats("sparse");
  }
  const std::vector<Mesh> meshes = expect_direct_equals_gmsh(paths);
  for (size_t i = 0; i < meshes.size(); ++i) {
    ASSERT_GT(meshes[i].num_nodes(), 50);
    // gmsh's MSH 2.2 writer numbers the nodes 1..N; 4.1 keeps the tags.
    if (fs::path(paths[i]).filename().string().find("_4") != std::string::npos) {
      EXPECT_EQ(meshes[i].node_tags.front(), 1007);
    }
  }
  const std::string hand22 = write_bytes("hand22.msh", R"($MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
1
1 9 "edge"
$EndPhysicalNames
$Nodes
5
900000 1 1 0
12 0 0 0
70000 +1 0 0
5 0 1 0
31 7 7 7
$EndNodes
$Elements
4
10 2 2 3 4 12 70000 900000
11 2 2 0 4 12 900000 5
12 1 2 9 2 12 70000
13 2 2 3 -1 12 70000 5
$EndElements
)");
  const std::string hand41 = write_bytes("hand41.msh", R"($MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
1
1 9 "edge"
$EndPhysicalNames
$Comments
anything $EndNodes
$EndComments
$Entities
0 1 1 0
2 0 0 0 1 0 0 1 9 0
4 0 0 0 1 1 0 1 3 0
$EndEntities
$Nodes
2 5 5 900000
2 4 0 4
900000
12
70000
5
1 1 0
0 0 0
1 0 0
0 1 0
0 31 0 1
31
7 7 7
$EndNodes
$Elements
2 3 10 12
2 4 2 2
10 12 70000 900000
11 12 900000 5
1 2 1 1
12 12 70000
$EndElements
$NodeData
1
"x"
1
0
3
0
1
1
12 2.5
$EndNodeData
)");
  for (const std::string& path : {hand22, hand41}) {
    const Mesh direct = read_msh(path);
    expect_same_mesh(direct, read_mesh_with_gmsh(path), path);
    EXPECT_EQ(direct.node_tags, (std::vector<int64_t>{5, 12, 70000, 900000})) << path;
    EXPECT_EQ(direct.num_cells(), 2) << path;
    EXPECT_EQ(direct.node_groups.at("edge"), (std::vector<int64_t>{1, 2})) << path;
    EXPECT_EQ(direct.node_groups.at("2:3").size(), 4u) << path;
  }
}

// Partitioned meshes are left to gmsh: read_msh refuses them, read_mesh hands them over.
TEST(MshReader, PartitionedMeshesAreLeftToGmsh) {
  std::vector<std::string> paths;
  {
    GmshSession session;
    gmsh::model::occ::addRectangle(0, 0, 0, 1, 1);
    gmsh::model::occ::synchronize();
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.2);
    gmsh::model::mesh::generate(2);
    gmsh::model::mesh::partition(2);
    for (double version : {2.2, 4.1}) {
      gmsh::option::setNumber("Mesh.MshFileVersion", version);
      paths.push_back(temp_path("part" + std::to_string(static_cast<int>(version * 10)) + ".msh"));
      gmsh::write(paths.back());
    }
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
  }
  for (const std::string& path : paths) {
    EXPECT_THROW(read_msh(path), MshNotHandled) << path;
    expect_same_mesh(read_mesh(path), read_mesh_with_gmsh(path), path);
  }
}

TEST(MshReader, DispatchesOnTheMeshFormatLine) {
  EXPECT_TRUE(is_direct_msh("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"));
  EXPECT_TRUE(is_direct_msh("\n\r\n  $MeshFormat\r\n2.2 1 8\r\n"));
  EXPECT_FALSE(is_direct_msh("$MeshFormat\n4 0 8\n"));
  EXPECT_FALSE(is_direct_msh("$MeshFormat\n4.0 0 8\n"));
  EXPECT_FALSE(is_direct_msh("$MeshFormat\n2.1 0 8\n"));
  EXPECT_FALSE(is_direct_msh("$MeshFormatX\n4.1 0 8\n"));
  EXPECT_FALSE(is_direct_msh("Point(1) = {0, 0, 0};\n"));
  EXPECT_FALSE(is_direct_msh("$NOD\n"));
  EXPECT_FALSE(is_direct_msh(""));
}

using test::kTwoTriangles;

std::string edited(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(MshReader, CrlfLineEndingsAreRead) {
  std::string crlf;
  for (const char* c = kTwoTriangles; *c; ++c)
    crlf += *c == '\n' ? std::string("\r\n") : std::string(1, *c);
  const std::string path = write_bytes("crlf.msh", crlf);
  const Mesh direct = read_msh(path);
  expect_same_mesh(direct, read_mesh_with_gmsh(path), path);
  EXPECT_EQ(direct.node_tags, (std::vector<int64_t>{3, 5, 8, 10}));
}

TEST(MshReader, BadTokensNameTheLineAndWhatWasExpected) {
  const std::string bad = write_bytes("bad_token.msh", edited(kTwoTriangles, "8 1 1 0", "8 x 1 0"));
  EXPECT_EQ(direct_error(bad),
            bad + ": line 9 in $Nodes: expected the x coordinate of a node, got 'x'");
  // read_mesh gives the same error (the direct reader takes the file).
  EXPECT_EQ(error_of([](const std::string& p) { return read_mesh(p); }, bad), direct_error(bad));
  const std::string comma = write_bytes("comma.msh", edited(kTwoTriangles, "5 1 0 0", "5 1,5 0 0"));
  EXPECT_EQ(direct_error(comma),
            comma + ": line 7 in $Nodes: expected the x coordinate of a node, got '1,5'");
  const std::string type =
      write_bytes("type.msh", edited(kTwoTriangles, "2 2 2 0 1", "2 250 2 0 1"));
  EXPECT_EQ(direct_error(type), type + ": line 15 in $Elements: unknown gmsh element type 250");
}

TEST(MshReader, WrongCountsAndMissingEndsAreRefused) {
  struct Case {
    std::string from, to, expected;
  };
  for (const Case& c : std::vector<Case>{
           {"$Nodes\n5\n", "$Nodes\n6\n",
            "line 11 in $Nodes: expected a node tag, got '$EndNodes'"},
           {"$Nodes\n5\n", "$Nodes\n4\n", "line 10 in $Nodes: expected $EndNodes, got '10'"},
           {"$Elements\n2\n", "$Elements\n3\n",
            "line 16 in $Elements: expected an element number, got '$EndElements'"},
           {"$EndNodes\n", "", "line 11 in $Nodes: expected $EndNodes, got '$Elements'"},
           {"$EndElements\n", "", "line 16 in $Elements: expected $EndElements, got end of file"},
           {"1 2 2 0 1 3 5 8", "1 2 2 0 1 3 5",
            "line 15 in $Elements: expected $EndElements, got '10'"},
           {"2.2 0 8", "2.2 2 8", "line 2 in $MeshFormat: file type must be 0 (ASCII) or 1"},
           {"1 2 2 0 1 3 5 8", "1 2 2 0 1 3 5 99", "cell references node tag 99 that has no"},
           {"7 9 9 0", "5 9 9 0", "node tag 5 is listed twice with different coordinates"},
       }) {
    const std::string path = write_bytes("counts.msh", edited(kTwoTriangles, c.from, c.to));
    const std::string error = direct_error(path);
    EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << error;
    EXPECT_NE(error.find(c.expected), std::string::npos) << error;
  }
}

// Counts far beyond the file's size are refused before anything is allocated.
TEST(MshReader, HugeCountsAreRefusedBeforeAllocation) {
  const std::string v2 =
      write_bytes("huge22.msh", edited(kTwoTriangles, "$Nodes\n5\n", "$Nodes\n1000000000000000\n"));
  EXPECT_NE(direct_error(v2).find(
                "line 5 in $Nodes: the file declares 1000000000000000 nodes, which need"),
            std::string::npos)
      << direct_error(v2);
  const std::string elements = write_bytes(
      "huge22e.msh", edited(kTwoTriangles, "$Elements\n2\n", "$Elements\n18446744073709551615\n"));
  EXPECT_NE(direct_error(elements).find("declares 18446744073709551615 elements"),
            std::string::npos)
      << direct_error(elements);
  const std::string over = write_bytes(
      "huge22o.msh", edited(kTwoTriangles, "$Nodes\n5\n", "$Nodes\n99999999999999999999\n"));
  EXPECT_NE(direct_error(over).find("expected the number of nodes, got '99999999999999999999'"),
            std::string::npos)
      << direct_error(over);
  // MSH 4.1, ASCII and binary: a node block and an element block claiming 1e15 entries.
  const std::vector<std::string> plate = plate_with_holes_files();
  const std::string ascii = read_bytes(plate[2]);
  const size_t nodes = ascii.find("\n", ascii.find("$Nodes\n") + 7);  // after the header line
  const size_t block = ascii.find("\n", nodes + 1);                   // first block header
  std::string text = ascii;
  const size_t last_space = text.rfind(' ', block);
  text.replace(last_space + 1, block - last_space - 1, "1000000000000000");
  const std::string huge41 = write_bytes("huge41.msh", text);
  EXPECT_NE(direct_error(huge41).find("in $Nodes: the file declares 1000000000000000 nodes"),
            std::string::npos)
      << direct_error(huge41);
  std::string binary = read_bytes(plate[3]);
  const size_t data = binary.find("$Nodes\n") + 7;
  const uint64_t huge = 1000000000000000ull;
  std::memcpy(&binary[data + 32 + 12], &huge, 8);  // header 4 x size_t, block dim/tag/param
  const std::string huge41b = write_bytes("huge41b.msh", binary);
  EXPECT_NE(direct_error(huge41b).find("byte " + std::to_string(data + 52) +
                                       " in $Nodes: the file declares 1000000000000000 nodes"),
            std::string::npos)
      << direct_error(huge41b);
}

// Every file cut short, anywhere: one InputError naming the file and the place (no crash).
TEST(MshReader, TruncatedFilesGiveOneClearError) {
  for (const std::string& path : plate_with_holes_files()) {
    const std::string bytes = read_bytes(path);
    const bool binary = path.find("b.msh") != std::string::npos;
    std::vector<size_t> cuts;
    for (double f : {0.02, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99}) cuts.push_back(bytes.size() * f);
    cuts.push_back(bytes.find("$EndElements"));
    cuts.push_back(bytes.find("$EndNodes") + 4);
    for (size_t cut : cuts) {
      const std::string cut_path = write_bytes("cut.msh", bytes.substr(0, cut));
      const std::string error =
          error_of([](const std::string& p) { return read_mesh(p); }, cut_path);
      EXPECT_EQ(error.rfind(cut_path + ": ", 0), 0u) << path << " cut at " << cut << ": " << error;
      EXPECT_NE(error.find(binary ? ": byte " : ": line "), std::string::npos)
          << path << " cut at " << cut << ": " << error;
      EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    }
  }
}

TEST(MshReader, UnsupportedCellsGiveTheGmshPathMessage) {
  const std::string mixed = write_bytes("mixed41.msh", R"($MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
1 5 1 5
2 1 0 5
1
2
3
4
5
0 0 0
1 0 0
1 1 0
0 1 0
2 0 0
$EndNodes
$Elements
2 2 1 2
2 1 3 1
1 1 2 3 4
2 1 2 1
2 2 5 3
$EndElements
)");
  const std::string error = direct_error(mixed);
  EXPECT_EQ(error, mixed +
                       ": unsupported or mixed cells of dimension 2 (Triangle 3, "
                       "Quadrilateral 4); bsms needs only 2-node lines, 3-node triangles or "
                       "4-node tetrahedra");
  const std::string gmsh_error =
      error_of([](const std::string& p) { return read_mesh_with_gmsh(p); }, mixed);
  EXPECT_NE(gmsh_error.find("unsupported or mixed cells of dimension 2"), std::string::npos);
  EXPECT_NE(gmsh_error.find("Quadrilateral 4"), std::string::npos) << gmsh_error;
  const std::string second_order = write_bytes(
      "tri6.msh", edited(edited(kTwoTriangles, "1 2 2 0 1 3 5 8", "1 9 2 0 1 3 5 8 7 10 3"),
                         "2 2 2 0 1 3 8 10", "2 9 2 0 1 3 8 10 7 5 3"));
  EXPECT_NE(direct_error(second_order).find("dimension 2 (Triangle 6)"), std::string::npos)
      << direct_error(second_order);
}

}  // namespace
}  // namespace bsms
