// Kernel properties: the paper's 1D closed form, partition of unity and linear reproduction on
// random particles, C¹ sample weights, gradient continuity across faces with and without η.
#include <gtest/gtest.h>

#include <map>
#include <vector>

#include "data/mpm/kernel.hpp"
#include "mpm_test_util.hpp"

namespace bsms::mpm {
namespace {

using testing::box_mesh;
using testing::random_point;

// Uniform unit 1D mesh with nodes 0..n-1.
BackgroundMesh<1> unit_line(int n) {
  RowMatrixXd points(n, 1);
  RowMatrixXi64 cells(n - 1, 2);
  for (int i = 0; i < n; ++i) points(i, 0) = i;
  for (int i = 0; i + 1 < n; ++i) cells.row(i) << i, i + 1;
  return make_background<1>(make_mesh(1, points, cells), false, "unit line");
}

template <int Dim>
std::map<int32_t, std::pair<double, Vec<Dim>>> kernel_at(const TransferKernel<Dim>& k,
                                                         const Vec<Dim>& x) {
  std::vector<KernelEntry<Dim>> out(k.max_entries());
  int32_t cell = -1;
  const int n = k.evaluate(x, cell, out.data());
  EXPECT_GT(n, 0);
  std::map<int32_t, std::pair<double, Vec<Dim>>> m;
  for (int i = 0; i < n; ++i) m[out[i].node] = {out[i].w, out[i].grad};
  return m;
}

TEST(UmlsKernel, MatchesPaperClosedForm1D) {
  // Appendix B of the journal paper: node at x = 2, unit mesh and unit B-spline length.
  const BackgroundMesh<1> bg = unit_line(7);
  const TransferKernel<1> umls(KernelType::kUmls, bg);
  auto k = kernel_at<1>(umls, Vec<1>(2.7));
  EXPECT_NEAR(k[2].first, 0.314684, 5e-7);
  EXPECT_NEAR(k[2].second[0], -0.923645, 5e-7);
  // Without η the same point gives another (discontinuous) kernel: 0.32 and -0.896.
  const TransferKernel<1> plain(KernelType::kUmlsNoEta, bg);
  auto p = kernel_at<1>(plain, Vec<1>(2.7));
  EXPECT_NEAR(p[2].first, 0.32, 1e-12);
  EXPECT_NEAR(p[2].second[0], -0.896, 1e-12);
  // Node 2 has no weight beyond 1.5 h (support of the sample weight).
  auto far = kernel_at<1>(umls, Vec<1>(3.6));
  EXPECT_EQ(far.count(2), 0u);
}

TEST(UmlsKernel, SampleWeightIsC1) {
  for (double q : {0.5, 1.5}) {
    const double e = 1e-7;
    EXPECT_NEAR(quadratic_bspline(q - e), quadratic_bspline(q + e), 1e-6);
    const double left = (quadratic_bspline(q - e) - quadratic_bspline(q - 2 * e)) / e;
    const double right = (quadratic_bspline(q + 2 * e) - quadratic_bspline(q + e)) / e;
    EXPECT_NEAR(left, right, 1e-5);
  }
  EXPECT_EQ(quadratic_bspline(1.5), 0.0);
}

template <int Dim>
void check_reproduction(KernelType type, const BackgroundMesh<Dim>& bg, int samples) {
  const TransferKernel<Dim> kernel(type, bg);
  std::vector<KernelEntry<Dim>> out(kernel.max_entries());
  std::mt19937 rng(7);
  const int32_t domain_cells = bg.num_domain_cells;
  int32_t cell = -1;
  for (int s = 0; s < samples; ++s) {
    const Vec<Dim> x = random_point<Dim>(bg, domain_cells, rng);
    const int n = kernel.evaluate(x, cell, out.data());
    ASSERT_GT(n, 0) << to_string(type) << " sample " << s;
    double sum_w = 0.0;
    Vec<Dim> sum_wx = Vec<Dim>::Zero(), sum_grad = Vec<Dim>::Zero();
    Mat<Dim> sum_xgrad = Mat<Dim>::Zero();
    for (int i = 0; i < n; ++i) {
      const Vec<Dim> r = (bg.points[out[i].node] - x) / bg.h;  // scale-free
      sum_w += out[i].w;
      sum_wx += out[i].w * r;
      sum_grad += out[i].grad * bg.h;
      sum_xgrad += r * (out[i].grad * bg.h).transpose();
    }
    EXPECT_NEAR(sum_w, 1.0, 1e-12) << to_string(type);
    EXPECT_LT(sum_wx.norm(), 1e-12) << to_string(type);
    EXPECT_LT(sum_grad.norm(), 1e-12) << to_string(type);
    EXPECT_LT((sum_xgrad - Mat<Dim>::Identity()).norm(), 1e-12) << to_string(type);
  }
}

TEST(UmlsKernel, PartitionOfUnityAndLinearReproduction2D) {
  const BackgroundMesh<2> bg = make_background<2>(box_mesh<2>(1.0, 0.1), true, "2D");
  for (KernelType t : {KernelType::kUmls, KernelType::kUmlsNoEta, KernelType::kLinearFem})
    check_reproduction<2>(t, bg, 2000);
}

TEST(UmlsKernel, PartitionOfUnityAndLinearReproduction3D) {
  const BackgroundMesh<3> bg = make_background<3>(box_mesh<3>(1.0, 0.25), true, "3D");
  for (KernelType t : {KernelType::kUmls, KernelType::kUmlsNoEta, KernelType::kLinearFem})
    check_reproduction<3>(t, bg, 1000);
}

TEST(BsplineKernel, PartitionOfUnityAndLinearReproduction) {
  const BackgroundMesh<2> bg2 = make_lattice<2>(Vec<2>(0, 0), Vec<2>(1, 1), 0.1, 2);
  const BackgroundMesh<3> bg3 = make_lattice<3>(Vec<3>(0, 0, 0), Vec<3>(1, 1, 1), 0.2, 2);
  // Random points inside [0, 1]^Dim.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const TransferKernel<2> k2(KernelType::kBspline, bg2);
  std::vector<KernelEntry<2>> out(k2.max_entries());
  for (int s = 0; s < 500; ++s) {
    const Vec<2> x(u(rng), u(rng));
    int32_t cell = 0;
    const int n = k2.evaluate(x, cell, out.data());
    ASSERT_EQ(n, 9);
    double sw = 0.0;
    Vec<2> swx = Vec<2>::Zero();
    Mat<2> sxg = Mat<2>::Zero();
    for (int i = 0; i < n; ++i) {
      sw += out[i].w;
      swx += out[i].w * (bg2.points[out[i].node] - x);
      sxg += (bg2.points[out[i].node] - x) * out[i].grad.transpose();
    }
    EXPECT_NEAR(sw, 1.0, 1e-12);
    EXPECT_LT(swx.norm(), 1e-12);
    EXPECT_LT((sxg - Mat<2>::Identity()).norm(), 1e-12);
  }
  const TransferKernel<3> k3(KernelType::kBspline, bg3);
  EXPECT_EQ(k3.max_entries(), 27);
}

// Smallest weight seen by particles sliding along the wall y = 0.001 of the unit box, away from
// its corners (the single mitred layer node at a corner still leaves small negative weights there).
double min_boundary_weight(const BackgroundMesh<2>& bg) {
  const TransferKernel<2> kernel(KernelType::kUmls, bg);
  std::vector<KernelEntry<2>> out(kernel.max_entries());
  double min_w = 1.0;
  for (double t = 0.25; t < 0.75; t += 0.005) {
    int32_t cell = -1;
    const int n = kernel.evaluate(Vec<2>(t, 0.001), cell, out.data());
    EXPECT_GT(n, 0);
    for (int i = 0; i < n; ++i) min_w = std::min(min_w, out[i].w);
  }
  return min_w;
}

TEST(UmlsKernel, ExtraLayerReducesNegativeBoundaryWeights) {
  // Paper Fig. 5: without samples beyond the wall the innermost node gets a negative weight.
  const Mesh mesh = box_mesh<2>(1.0, 0.1);
  const BackgroundMesh<2> with = make_background<2>(mesh, true, "layer");
  const BackgroundMesh<2> without = make_background<2>(mesh, false, "no layer");
  const double w_with = min_boundary_weight(with), w_without = min_boundary_weight(without);
  EXPECT_LT(w_without, -0.01);
  EXPECT_GT(w_with, -1e-9);
  EXPECT_GT(with.num_nodes(), with.num_domain_nodes);
  EXPECT_EQ(without.num_nodes(), without.num_domain_nodes);
}

// Largest change of any weight gradient when a particle crosses an interior face by ±eps.
template <int Dim>
double max_gradient_jump(KernelType type, const BackgroundMesh<Dim>& bg, int32_t domain_cells,
                         double eps, int samples) {
  const TransferKernel<Dim> kernel(type, bg);
  std::mt19937 rng(11);
  std::uniform_int_distribution<int32_t> pick(0, domain_cells - 1);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  double worst = 0.0;
  for (int s = 0; s < samples; ++s) {
    const int32_t c = pick(rng);
    const int k = s % (Dim + 1);
    if (bg.neighbours[c][k] < 0) continue;
    // A point on the face opposite vertex k, and the face normal.
    Vec<Dim> x = Vec<Dim>::Zero();
    double rest = 1.0;
    for (int i = 0, j = 0; i <= Dim; ++i) {
      if (i == k) continue;
      const double b = (++j == Dim) ? rest : rest * u(rng);
      rest -= b;
      x += b * bg.points[bg.cells[c][i]];
    }
    const Vec<Dim> n = (bg.points[bg.cells[c][k]] - x).normalized();
    auto before = kernel_at<Dim>(kernel, Vec<Dim>(x + eps * bg.h * n));
    auto after = kernel_at<Dim>(kernel, Vec<Dim>(x - eps * bg.h * n));
    std::map<int32_t, Vec<Dim>> diff;
    for (auto& [v, wg] : before) diff.emplace(v, Vec<Dim>::Zero()).first->second += wg.second;
    for (auto& [v, wg] : after) diff.emplace(v, Vec<Dim>::Zero()).first->second -= wg.second;
    for (auto& [v, d] : diff) worst = std::max(worst, d.norm() * bg.h);
  }
  return worst;
}

TEST(UmlsKernel, GradientContinuousAcrossFacesOnlyWithEta2D) {
  // Graded mesh: h (maximum edge) is ~4x the smallest elements, so N¹ changes inside the support.
  const Mesh mesh = box_mesh<2>(1.0, 0.2, true);
  const BackgroundMesh<2> bg = make_background<2>(mesh, true, "graded");
  const int32_t cells = static_cast<int32_t>(mesh.num_cells());
  const double with_eta = max_gradient_jump<2>(KernelType::kUmls, bg, cells, 1e-9, 400);
  const double without = max_gradient_jump<2>(KernelType::kUmlsNoEta, bg, cells, 1e-9, 400);
  const double fem = max_gradient_jump<2>(KernelType::kLinearFem, bg, cells, 1e-9, 400);
  EXPECT_LT(with_eta, 1e-6);
  EXPECT_GT(without, 1e-3);
  EXPECT_GT(fem, 1e-1);
  // Halving the crossing distance halves the jump with η (it is O(eps)).
  const double half = max_gradient_jump<2>(KernelType::kUmls, bg, cells, 0.5e-9, 400);
  EXPECT_LT(half, 0.75 * with_eta + 1e-12);
}

TEST(UmlsKernel, GradientContinuousAcrossFacesOnlyWithEta3D) {
  const Mesh mesh = box_mesh<3>(1.0, 0.3, true);
  const BackgroundMesh<3> bg = make_background<3>(mesh, true, "graded 3D");
  const int32_t cells = static_cast<int32_t>(mesh.num_cells());
  EXPECT_LT(max_gradient_jump<3>(KernelType::kUmls, bg, cells, 1e-9, 200), 1e-6);
  EXPECT_GT(max_gradient_jump<3>(KernelType::kUmlsNoEta, bg, cells, 1e-9, 200), 1e-3);
}

TEST(BackgroundMesh, LocateFindsTheContainingCellOrReportsOutside) {
  const BackgroundMesh<2> bg = make_background<2>(box_mesh<2>(1.0, 0.1), true, "locate");
  std::mt19937 rng(5);
  Eigen::Matrix<double, 3, 1> bary;
  int32_t hint = 0;
  for (int s = 0; s < 1000; ++s) {
    const Vec<2> x = random_point<2>(bg, bg.num_cells(), rng);
    hint = bg.locate(x, hint, bary);
    ASSERT_GE(hint, 0);
    EXPECT_GE(bary.minCoeff(), -1e-12);
    EXPECT_NEAR(bary.sum(), 1.0, 1e-12);
  }
  EXPECT_EQ(bg.locate(Vec<2>(5.0, 5.0), hint, bary), -1);
  EXPECT_EQ(bg.locate(Vec<2>(-0.5, 0.5), -1, bary), -1);  // beyond the extra layer (h ~ 0.1)
}

}  // namespace
}  // namespace bsms::mpm
