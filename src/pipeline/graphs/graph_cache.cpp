#include "pipeline/graphs/graph_cache.hpp"

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "core/error.hpp"
#include "core/one_line.hpp"
#include "preprocess/multilevel_file.hpp"

namespace bsms {
namespace fs = std::filesystem;

std::string topology_key(const TrajectoryMesh& mesh) {
  uint64_t h = 1469598103934665603ull;
  auto mix = [&h](uint64_t v) {
    for (int b = 0; b < 8; ++b) {
      h ^= (v >> (8 * b)) & 0xffu;
      h *= 1099511628211ull;
    }
  };
  mix(static_cast<uint64_t>(mesh.num_nodes()));
  mix(static_cast<uint64_t>(mesh.cell_size));
  for (int32_t c : mesh.cells) mix(static_cast<uint32_t>(c));
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

Mesh to_mesh(const TrajectoryMesh& m) {
  const int64_t n = m.num_nodes();
  RowMatrixXd points(n, m.dim);
  for (int64_t i = 0; i < n; ++i)
    for (int c = 0; c < m.dim; ++c) points(i, c) = m.mesh_pos[i * m.dim + c];
  RowMatrixXi64 cells(m.num_cells(), m.cell_size);
  for (int64_t c = 0; c < m.num_cells(); ++c)
    for (int a = 0; a < m.cell_size; ++a) cells(c, a) = m.cells[c * m.cell_size + a];
  return make_mesh(m.dim, std::move(points), std::move(cells));
}

std::string multilevel_cache_name(Seeding seeding, int levels, const std::string& key,
                                  uint64_t rng_seed) {
  const std::string name = seeding == Seeding::kRandom
                               ? to_string(seeding) + "-s" + std::to_string(rng_seed)
                               : to_string(seeding);
  return name + "-L" + std::to_string(levels) + "-" + key + ".h5";
}

int auto_levels(const TrajectoryMesh& mesh, Seeding seeding) {
  BuildOptions options;
  options.seeding = seeding;
  options.num_levels = 0;
  options.thinning = Thinning::kOff;  // training builds exact A² hierarchies of this depth
  return build_multilevel_graph(to_mesh(mesh), options).num_levels();
}

MultilevelCache::MultilevelCache(Seeding seeding, int levels, std::vector<std::string> cache_dirs,
                                 uint64_t rng_seed, bool require_write)
    : seeding_(seeding),
      levels_(levels),
      rng_seed_(rng_seed),
      cache_dirs_(std::move(cache_dirs)),
      require_write_(require_write) {
  if (levels_ < 1) throw InputError("graph levels must be >= 1");
}

CachedMultilevel MultilevelCache::load_or_build(const TrajectoryMesh& mesh) {
  const std::string key = topology_key(mesh);
  CachedMultilevel entry;
  entry.key = key;
  const Mesh core_mesh = to_mesh(mesh);
  entry.mesh_pos = core_mesh.points;
  const std::string name = multilevel_cache_name(seeding_, levels_, key, rng_seed_);
  bool loaded = false;
  for (const auto& dir : cache_dirs_) {
    const std::string path = (fs::path(dir) / name).string();
    if (!fs::exists(path)) continue;
    std::string problem;
    try {
      MultilevelGraph cached = read_multilevel_graph(path);
      if (cached.num_levels() == levels_ && cached.levels[0].num_nodes() == mesh.num_nodes()) {
        entry.multilevel = std::move(cached);
        entry.from_cache = loaded = true;
        break;
      }
      problem = "holds " + std::to_string(cached.num_levels()) + " levels of " +
                std::to_string(cached.levels.empty() ? 0 : cached.levels[0].num_nodes()) +
                " nodes, expected " + std::to_string(levels_) + " of " +
                std::to_string(mesh.num_nodes());
    } catch (const InputError& e) {
      problem = e.what();
    }
    std::cerr << "bsms: warning: "
              << one_line("cached graph " + path + " not used (" + problem + ")")
              << "; rebuilding it\n";
  }
  if (!loaded) {
    BuildOptions options;
    options.seeding = seeding_;
    options.num_levels = levels_;
    options.rng_seed = rng_seed_;
    entry.multilevel = build_multilevel_graph(core_mesh, options);
    std::string failure;
    for (const auto& dir : cache_dirs_) {
      try {
        write_multilevel_graph(entry.multilevel, (fs::path(dir) / name).string());
        failure.clear();
        break;
      } catch (const std::exception& e) {
        // Not writable here: try the next folder; the graph stays in memory either way.
        if (failure.empty()) failure = e.what();
      }
    }
    if (!failure.empty() && require_write_)
      throw IoError("cannot write the multilevel graph " + name + ": " + failure);
    if (!failure.empty() && !warned_write_.exchange(true)) {
      std::cerr << "bsms: warning: graphs are kept in memory only, no cache folder took them ("
                << one_line(failure) << ")\n";
    }
  }
  const CsrGraph& g = entry.multilevel.levels[0].graph;
  double total = 0;
  for (int64_t i = 0; i < g.num_nodes; ++i)
    for (const int64_t* j = g.begin(i); j != g.end(i); ++j)
      total += (core_mesh.points.row(i) - core_mesh.points.row(*j)).norm();
  entry.mean_edge_length = g.num_edges() > 0 ? total / static_cast<double>(g.num_edges()) : 1.0;
  return entry;
}

}  // namespace bsms
