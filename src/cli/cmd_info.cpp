// bsms info FILE|RUN: summarises a dataset, a multilevel graph file, simulation frames or a run.
#include <filesystem>
#include <iomanip>
#include <iostream>

#include "cli/command.hpp"
#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/dataset.hpp"

namespace {

namespace fs = std::filesystem;

void info_dataset(const std::string& path) {
  const bsms::Dataset d(path);
  int64_t frames = 0, nodes = 0, cells = 0;
  std::map<int32_t, int64_t> types;
  for (int64_t t = 0; t < d.num_trajectories(); ++t) {
    frames += d.num_frames(t);
    const auto& m = d.mesh(t);
    nodes += m.num_nodes();
    cells += m.num_cells();
    for (int32_t v : m.node_type) ++types[v];
  }
  const double k = static_cast<double>(d.num_trajectories());
  std::cout << path << ": "
            << (d.is_public_layout() ? "public MeshGraphNets layout" : "bsms dataset")
            << "\n  dimension " << d.dim() << ", frame dt " << d.frame_dt() << " s\n  "
            << d.num_trajectories() << " trajectories, mean " << std::fixed << std::setprecision(1)
            << frames / k << " frames, " << nodes / k << " nodes, " << cells / k
            << " cells\n  fields:";
  for (const auto& f : d.fields()) std::cout << ' ' << f.name << '[' << f.width << ']';
  std::cout << "\n  node types:";
  for (const auto& [type, count] : types) std::cout << ' ' << type << ':' << count;
  std::cout << '\n';
}

void info_multilevel(const bsms::H5File& f) {
  const int64_t levels = f.attr_int("/", "num_levels");
  std::cout << f.path() << ": bsms multilevel graph, seeding " << f.attr_string("/", "seeding")
            << ", " << levels << " levels\n  level      nodes      edges  mean degree\n";
  for (int64_t k = 0; k < levels; ++k) {
    const std::string g = "/level_" + std::to_string(k);
    const int64_t n = f.attr_int(g, "num_nodes");
    const int64_t e = static_cast<int64_t>(f.shape(g + "/edges")[0]);
    std::cout << std::setw(7) << k << std::setw(11) << n << std::setw(11) << e << std::setw(13)
              << std::fixed << std::setprecision(2) << (n ? static_cast<double>(e) / n : 0.0)
              << '\n';
  }
}

void info_frames(const bsms::H5File& f) {
  const auto pos = f.shape("/frames/position");
  std::cout << f.path() << ": bsms simulation frames, dimension " << f.attr_int("/", "dim")
            << ", kernel " << f.attr_string("/", "kernel") << ", transfer "
            << f.attr_string("/", "transfer") << "\n  " << pos[0] << " frames of " << pos[1]
            << " particles\n";
}

void info_run(const std::string& run) {
  std::cout << run << ": bsms run\n";
  for (const char* name : {"config.json", "train_stats.json", "rollout/metrics.json"}) {
    const fs::path p = fs::path(run) / name;
    if (!fs::exists(p)) continue;
    bsms::Json j = bsms::load_json_file(p.string());
    if (j.contains("rmse_per_step")) j.erase("rmse_per_step");
    std::cout << "  " << name << ":\n" << j.dump(2) << '\n';
  }
}

void info(const std::string& path) {
  if (fs::is_directory(path)) {
    if (fs::exists(fs::path(path) / "config.json")) return info_run(path);
    return info_dataset(path);  // public layout folder
  }
  const bsms::H5File f(path, bsms::H5File::Mode::kRead);
  const std::string format = f.has_attr("/", "format") ? f.attr_string("/", "format") : "";
  if (format == "bsms-dataset") return info_dataset(path);
  if (format == "bsms-multilevel") return info_multilevel(f);
  if (format == "bsms-frames") return info_frames(f);
  if (f.exists("/mesh_pos")) return info_dataset(fs::path(path).parent_path().string());
  throw bsms::InputError(path + ": unknown file (format attribute '" + format +
                         "'; expected bsms-dataset, bsms-multilevel or bsms-frames)");
}

BSMS_COMMAND("info", "summarise a dataset, multilevel graph file, frames file or run folder",
             [](CLI::App& sub) {
               auto path = std::make_shared<std::string>();
               sub.add_option("file", *path, "HDF5 file or run folder")->required();
               sub.callback([path] { info(*path); });
             });

}  // namespace
