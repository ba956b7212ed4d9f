// The symmetries of box scenes (counted against the group orders a square, a rectangle, a cube,
// gravity and unequal walls leave) and their action on points, vectors and meshes.
#include "pipeline/adapters/scene_symmetry.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "plate_data.hpp"
#include "scene_text.hpp"

namespace bsms {
namespace {

// The typed scene of a family file whose base scene is a box from `min` to `max` (JSON lists of
// `dim` numbers) with these sides' boundary types.
std::optional<mpm::Scene> box_scene(const std::string& min, const std::string& max,
                                    const std::vector<std::pair<std::string, std::string>>& sides,
                                    const std::string& gravity = "") {
  std::string boundaries;
  for (const auto& [group, type] : sides)
    boundaries += std::string(boundaries.empty() ? "" : ",") + R"({"group": ")" + group +
                  R"(", "type": ")" + type + R"("})";
  const int dim = 1 + static_cast<int>(std::count(min.begin(), min.end(), ','));
  return testing::typed_scene(R"({"family": "disks", "scene": {"dim": )" + std::to_string(dim) +
                                  R"(, "background": {"type": "box", "min": )" + min +
                                  R"(, "max": )" + max +
                                  R"(, "element_size": 0.1}, "boundaries": [)" + boundaries + "]" +
                                  (gravity.empty() ? "" : R"(, "gravity": )" + gravity) +
                                  R"(, "solver": {"end_time": 1.0}}})",
                              dim);
}

const std::vector<std::pair<std::string, std::string>> kSlip2d = {
    {"left", "slip"}, {"right", "slip"}, {"bottom", "slip"}, {"top", "slip"}};

TEST(SceneSymmetry, CountsTheGroupEachBoxLeaves) {
  // The square: the dihedral group of order 8, identity first, all distinct.
  const auto square = scene_symmetries(box_scene("[0, 0]", "[1, 1]", kSlip2d), 2);
  ASSERT_EQ(square.size(), 8u);
  EXPECT_TRUE(square[0].is_identity());
  std::set<std::pair<std::vector<int>, std::vector<int>>> distinct;
  for (const auto& g : square) {
    distinct.insert({g.source, g.sign});
    EXPECT_EQ(g.centre, (std::vector<double>{0.5, 0.5}));
  }
  EXPECT_EQ(distinct.size(), 8u);
  // A 2 x 1 rectangle: reflections only (4); gravity along -y keeps only the x reflection.
  EXPECT_EQ(scene_symmetries(box_scene("[0, 0]", "[2, 1]", kSlip2d), 2).size(), 4u);
  const auto falling = scene_symmetries(box_scene("[0, 0]", "[1, 1]", kSlip2d, "[0, -9.8]"), 2);
  ASSERT_EQ(falling.size(), 2u);
  EXPECT_EQ(falling[1].source, (std::vector<int>{0, 1}));
  EXPECT_EQ(falling[1].sign, (std::vector<int>{-1, 1}));
  // A fixed right wall against a slip left one: only the y reflection is left.
  const auto sticky = scene_symmetries(
      box_scene("[0, 0]", "[1, 1]",
                {{"left", "slip"}, {"right", "fixed"}, {"bottom", "slip"}, {"top", "slip"}}),
      2);
  ASSERT_EQ(sticky.size(), 2u);
  EXPECT_EQ(sticky[1].sign, (std::vector<int>{1, -1}));
  // The cube: the full group of signed permutations, 2^3 * 3! = 48.
  EXPECT_EQ(scene_symmetries(box_scene("[0, 0, 0]", "[1, 1, 1]",
                                       {{"left", "slip"},
                                        {"right", "slip"},
                                        {"bottom", "slip"},
                                        {"top", "slip"},
                                        {"back", "slip"},
                                        {"front", "slip"}}),
                             3)
                .size(),
            48u);
  // No scene, no box, a boundary that is no side of it, two types on one side or a rotated box:
  // the identity alone, and why.
  const std::string box =
      R"("dim": 2, "solver": {"end_time": 1.0}, "background": {"type": "box", "min": [0, 0], )"
      R"("max": [1, 1], "element_size": 0.1)";
  for (const std::string& scene :
       {std::string("{}"), std::string(testing::kPlateScene),
        R"({"scene": {)" + box +
            R"(}, "boundaries": [{"point": [0, 0], "normal": [1, 1], "type": "slip"}]}})",
        R"({"scene": {)" + box +
            R"(}, "boundaries": [{"group": "left", "type": "slip"},
                                 {"group": "left", "type": "fixed"}]}})",
        R"({"scene": {)" + box + R"(, "rotation_deg": 30}}})"}) {
    std::string why;
    const auto only = scene_symmetries(testing::typed_scene(scene), 2, &why);
    ASSERT_EQ(only.size(), 1u) << scene;
    EXPECT_TRUE(only[0].is_identity());
    EXPECT_FALSE(why.empty()) << scene;
  }
  // A boundary type or a rotation that is no value is refused where the scene is read.
  for (const std::string& scene :
       {R"({"scene": {)" + box + R"(}, "boundaries": [{"group": "left", "type": 3}]}})",
        R"({"scene": {)" + box + R"(, "rotation_deg": "a"}}})"})
    EXPECT_THROW(testing::typed_scene(scene), InputError) << scene;
}

TEST(SceneSymmetry, MapsTheBoxOntoItselfAndVectorsBack) {
  const auto group = scene_symmetries(box_scene("[-1, 2]", "[3, 6]", kSlip2d), 2);
  ASSERT_EQ(group.size(), 8u);
  const auto corners =
      torch::tensor({-1.0f, 2.0f, 3.0f, 2.0f, 3.0f, 6.0f, -1.0f, 6.0f}).view({4, 2});
  torch::manual_seed(3);
  const auto v = torch::randn({5, 2});
  for (const auto& g : group) {
    // Corners go to corners (the set, in some order); the centre stays.
    const auto mapped = g.points(corners);
    for (int64_t k = 0; k < 4; ++k) {
      const auto d = (corners - mapped[k]).abs().sum(1);
      EXPECT_LT(d.min().item<float>(), 1e-6f) << k;
    }
    EXPECT_TRUE(
        torch::allclose(g.points(torch::tensor({{1.0f, 4.0f}})), torch::tensor({{1.0f, 4.0f}})));
    // Vectors: an isometry, undone by vectors_back; points move by the vector map of differences.
    EXPECT_TRUE(torch::allclose(g.vectors_back(g.vectors(v)), v));
    EXPECT_NEAR(g.vectors(v).norm().item<float>(), v.norm().item<float>(), 1e-5);
    EXPECT_TRUE(torch::allclose(g.points(corners + v.narrow(0, 0, 4)) - g.points(corners),
                                g.vectors(v.narrow(0, 0, 4)), 1e-5, 1e-5));
    // The mesh's reference positions move like points; topology and bodies stay.
    TrajectoryMesh m;
    m.dim = 2;
    m.cell_size = 3;
    m.mesh_pos = {-1.0f, 2.0f, 3.0f, 2.0f, 3.0f, 6.0f};
    m.cells = {0, 1, 2};
    m.node_type = {0, 0, 1};
    m.body_id = {0, 0, 0};
    const TrajectoryMesh out = g.mesh(m);
    const auto expected = g.points(torch::tensor(m.mesh_pos).view({3, 2}));
    EXPECT_TRUE(torch::allclose(torch::tensor(out.mesh_pos).view({3, 2}), expected));
    EXPECT_EQ(out.cells, m.cells);
    EXPECT_EQ(out.node_type, m.node_type);
  }
  // The group is closed: composing any two gives a member.
  for (const auto& a : group)
    for (const auto& b : group) {
      const auto p = torch::tensor({{0.3f, 5.1f}});
      const auto ab = a.points(b.points(p));
      bool found = false;
      for (const auto& c : group) found = found || torch::allclose(c.points(p), ab, 1e-5, 1e-5);
      EXPECT_TRUE(found);
    }
}

}  // namespace
}  // namespace bsms
