#include "pipeline/report/animation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "core/error.hpp"
#include "pipeline/report/plotting.hpp"

namespace bsms {
namespace fs = std::filesystem;

std::vector<std::pair<int32_t, int32_t>> drawn_edges(const TrajectoryMesh& mesh) {
  const int k = mesh.cell_size;
  std::vector<std::pair<int32_t, int32_t>> edges;
  auto add = [&edges](int32_t a, int32_t b) { edges.emplace_back(std::min(a, b), std::max(a, b)); };
  if (k == 4) {
    // A face of a tetrahedron is on the boundary when no other tetrahedron shares it.
    std::map<std::array<int32_t, 3>, int> faces;
    for (int64_t c = 0; c < mesh.num_cells(); ++c) {
      const int32_t* v = &mesh.cells[c * 4];
      for (int skip = 0; skip < 4; ++skip) {
        std::array<int32_t, 3> f{};
        for (int i = 0, j = 0; i < 4; ++i)
          if (i != skip) f[j++] = v[i];
        std::sort(f.begin(), f.end());
        ++faces[f];
      }
    }
    for (const auto& [f, count] : faces)
      if (count == 1) {
        add(f[0], f[1]);
        add(f[1], f[2]);
        add(f[0], f[2]);
      }
  } else {
    for (int64_t c = 0; c < mesh.num_cells(); ++c)
      for (int a = 0; a < k; ++a)
        for (int b = a + 1; b < k; ++b) add(mesh.cells[c * k + a], mesh.cells[c * k + b]);
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

double rms_distance(const std::vector<float>& a, const std::vector<float>& b, int dim) {
  if (a.size() != b.size() || dim <= 0) throw InputError("rms_distance: frames of different sizes");
  const size_t n = a.size() / static_cast<size_t>(dim);
  if (n == 0) return 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = static_cast<double>(a[i]) - static_cast<double>(b[i]);
    sum += d * d;
  }
  return std::sqrt(sum / static_cast<double>(n));
}

namespace {

// One frame's edges as gnuplot segments ("x y [z]" pairs, a blank line after each); a second
// blank line ends the frame's block, so that `index f` selects frame f.
void write_frame(std::ofstream& f, const std::vector<std::pair<int32_t, int32_t>>& edges,
                 const std::vector<float>& x, int dim) {
  auto point = [&](int32_t i) {
    for (int c = 0; c < dim; ++c)
      f << x[static_cast<size_t>(i) * dim + c] << (c + 1 < dim ? ' ' : '\n');
  };
  for (const auto& [a, b] : edges) {
    point(a);
    point(b);
    f << '\n';
  }
  f << '\n';
}

}  // namespace

bool animate_rollout(const Dataset& d, const std::string& plots, const std::string& name,
                     const std::string& title) {
  const int dim = d.dim();
  const int64_t frames = d.num_frames(0);
  if ((dim != 2 && dim != 3) || frames < 1) return false;
  const auto edges = drawn_edges(d.mesh(0));
  const fs::path dir = plots;
  const fs::path truth_file = dir / (name + "_truth.dat"), pred_file = dir / (name + "_pred.dat");
  std::vector<double> errors(static_cast<size_t>(frames));
  std::array<double, 3> lo, hi;
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  {
    std::ofstream truth(truth_file), pred(pred_file);
    truth.precision(6);
    pred.precision(6);
    for (int64_t t = 0; t < frames; ++t) {
      const std::vector<float> x = d.read(0, "target_world_pos", t);
      const std::vector<float> y = d.read(0, "world_pos", t);
      errors[static_cast<size_t>(t)] = rms_distance(y, x, dim);
      for (size_t i = 0; i < x.size(); ++i) {
        lo[i % dim] = std::min(lo[i % dim], static_cast<double>(x[i]));
        hi[i % dim] = std::max(hi[i % dim], static_cast<double>(x[i]));
      }
      write_frame(truth, edges, x, dim);
      write_frame(pred, edges, y, dim);
    }
    if (!truth || !pred) throw IoError(truth_file.string() + ": cannot write the animation data");
  }
  // Axes: the truth's extent with a margin of 5 % of its largest side (predictions that leave it
  // are cut at the frame, as they leave the scene).
  double side = 0.0;
  for (int c = 0; c < dim; ++c) side = std::max(side, hi[c] - lo[c]);
  const double margin = 0.05 * (side > 0 ? side : 1.0);
  std::ostringstream g;
  g.precision(8);
  g << gnuplot_gif_preamble((dir / (name + ".gif")).string(), dim == 3 ? 800 : 900, 600)
    << "unset key\n";
  const char* axes[] = {"x", "y", "z"};
  for (int c = 0; c < dim; ++c)
    g << "set " << axes[c] << "range [" << lo[c] - margin << ":" << hi[c] + margin << "]\n";
  if (dim == 3)
    g << "set view equal xyz\nset view 60, 30, 1.6\nset xyplane at " << lo[2] - margin
      << "\nset tics font ',8'\nset format '%.2g'\n";
  else
    g << "set size ratio -1\n";
  g << "array err[" << frames << "] = [";
  for (int64_t t = 0; t < frames; ++t) g << (t ? "," : "") << errors[static_cast<size_t>(t)];
  g << "]\n"
    << "do for [f=0:" << frames - 1 << "] {\n"
    << "  set title " << gnuplot_quoted(title)
    << " . \"\\n\" . sprintf('frame %d / %d   RMS node distance %.3g m', f, " << frames - 1
    << ", err[f+1])\n"
    << "  " << (dim == 3 ? "splot " : "plot ") << gnuplot_quoted(truth_file.string())
    << " index f with lines lc rgb '#999999' lw 2, " << gnuplot_quoted(pred_file.string())
    << " index f with lines lc rgb '#d62728' lw 1\n}\n";
  return draw_plot((dir / (name + ".gp")).string(), g.str());
}

}  // namespace bsms
