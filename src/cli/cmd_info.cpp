// bsms info FILE|RUN: summarises a dataset (bsms, public HDF5 layouts, a MeshGraphNets folder or
// one of its .tfrecord splits), a multilevel graph file, simulation frames, a run or a training
// checkpoint (RUN/checkpoints/latest.h5).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>

#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/dataset.hpp"
#include "data/dataset/tfrecord.hpp"
#include "models/checkpoint_format.hpp"
#include "pipeline/runs/run_files.hpp"

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
  std::cout << path << ": " << bsms::layout_name(d.layout()) << "\n  dimension " << d.dim()
            << ", frame dt " << d.frame_dt() << " s\n  " << d.num_trajectories()
            << " trajectories, mean " << std::fixed << std::setprecision(1) << frames / k
            << " frames, " << nodes / k << " nodes, " << cells / k << " cells\n  fields:";
  for (const auto& f : d.fields()) std::cout << ' ' << f.name << '[' << f.width << ']';
  std::cout << "\n  node types:";
  for (const auto& [type, count] : types) std::cout << ' ' << type << ':' << count;
  // Generated data: what the solver cost and how many draws it lost (each trajectory records
  // the attempt that succeeded; every earlier attempt was an unstable draw, redrawn).
  std::vector<double> ms_per_frame;
  int64_t redrawn = 0, redrawn_trajectories = 0, with_attempt = 0;
  for (int64_t t = 0; t < d.num_trajectories(); ++t) {
    const double s = d.solver_wall_s(t);
    if (s >= 0 && d.num_frames(t) > 1)
      ms_per_frame.push_back(1000.0 * s / static_cast<double>(d.num_frames(t) - 1));
    const bsms::Json p = bsms::Json::parse(d.parameters(t), nullptr, false);
    if (p.is_object() && p.contains("attempt") && p["attempt"].is_number_integer()) {
      const int64_t attempt = p["attempt"].get<int64_t>();
      ++with_attempt;
      redrawn += attempt;
      redrawn_trajectories += attempt > 0 ? 1 : 0;
    }
  }
  if (!ms_per_frame.empty()) {
    std::sort(ms_per_frame.begin(), ms_per_frame.end());
    const size_t h = ms_per_frame.size() / 2;
    const double median = ms_per_frame.size() % 2 == 1
                              ? ms_per_frame[h]
                              : 0.5 * (ms_per_frame[h - 1] + ms_per_frame[h]);
    std::cout << "\n  solver: " << std::setprecision(2) << median
              << " ms per frame (median, single-threaded solve)";
  }
  if (with_attempt > 0)
    std::cout << "\n  unstable draws redrawn: " << redrawn << " (in " << redrawn_trajectories
              << " of " << with_attempt << " trajectories)";
  std::cout << '\n' << std::defaultfloat << std::setprecision(6);  // for the next summary
}

// A MeshGraphNets folder (meta.json + {split}.tfrecord): the schema, record counts and the first
// trajectory's mesh. Reads record headers and one record only (a real split is ~13 GB).
void info_meshgraphnets(const std::string& dir, const std::string& only_split = "") {
  std::vector<std::string> splits;
  if (!only_split.empty()) splits.push_back(only_split);
  for (const char* split : {"train", "valid", "test"})
    if (only_split.empty() && fs::exists(fs::path(dir) / (std::string(split) + ".tfrecord")))
      splits.push_back(split);
  if (splits.empty())
    throw bsms::InputError(dir + ": meta.json but no train, valid or test .tfrecord");
  // Opening a split checks the schema (e.g. rejects remeshing data) before anything is printed.
  const bsms::Dataset first = bsms::Dataset::open_split(dir, splits[0]);
  const bsms::TrajectoryMesh& mesh = first.mesh(0);
  const bsms::tfrecord::Meta meta =
      bsms::tfrecord::read_meta((fs::path(dir) / "meta.json").string());
  std::ostringstream out;
  out << dir << ": " << bsms::layout_name(first.layout()) << " dataset\n  simulator "
      << (meta.simulator.empty() ? "(not stated)" : meta.simulator) << ", dt " << meta.dt
      << " s, collision radius ";
  if (meta.collision_radius > 0)
    out << meta.collision_radius;
  else
    out << "none";
  out << ", trajectory length " << meta.trajectory_length << " frames, dimension " << first.dim()
      << "\n  splits:";
  for (const auto& split : splits) {
    const std::string path = (fs::path(dir) / (split + ".tfrecord")).string();
    const bsms::tfrecord::TfRecordReader reader(path, meta);
    const double mib = static_cast<double>(fs::file_size(path)) / (1024.0 * 1024.0);
    char size[32];
    std::snprintf(size, sizeof size, mib < 1 ? "%.0f KiB" : "%.1f MiB", mib < 1 ? mib * 1024 : mib);
    out << (split == splits[0] ? " " : ", ") << split << ' ' << reader.num_records() << " records ("
        << size << ')';
  }
  out << "\n  fields:\n";
  for (const auto& f : meta.fields)
    out << "    " << std::left << std::setw(12) << f.name << std::setw(15)
        << bsms::tfrecord::kind_name(f.kind) << std::setw(14)
        << bsms::tfrecord::shape_string(f.shape) << bsms::tfrecord::dtype_name(f.dtype) << '\n';
  std::map<int32_t, int64_t> types;
  for (int32_t v : mesh.node_type) ++types[v];
  out << std::right << "  first trajectory (" << splits[0] << " record 0): " << mesh.num_nodes()
      << " nodes, " << mesh.num_cells() << " cells of " << mesh.cell_size
      << " nodes\n  node types:";
  for (const auto& [type, count] : types) out << ' ' << type << ':' << count;
  std::cout << out.str() << '\n';
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

// A checkpoint's summary comes from bsms-torch, which can read its tensors: the front end hands the
// whole command to it (programs.hpp).
std::string describe_checkpoint(const std::string& path, const std::string& indent = "") {
  const bsms::cli::CheckpointDescriber describe = bsms::cli::checkpoint_describer();
  if (describe == nullptr)
    throw bsms::SilentExit(bsms::cli::run_in_program(bsms::cli::Program::kTorch));
  return describe(path, indent);
}

void info_run(const std::string& run) {
  // The checkpoint is read (and checked) before anything is printed: a damaged one is an error,
  // not half a summary.
  const std::string checkpoint = bsms::run_checkpoint_path(run);
  std::string described;
  if (fs::exists(checkpoint)) {
    described = describe_checkpoint(checkpoint, "  ");
  } else {
    const std::string legacy = bsms::legacy_checkpoint_path(checkpoint);
    if (fs::exists(legacy)) throw bsms::InputError(bsms::legacy_checkpoint_message(legacy));
  }
  std::cout << run << ": bsms run\n";
  for (const char* name : {"config.json", "train_stats.json", "rollout/metrics.json"}) {
    const fs::path p = fs::path(run) / name;
    if (!fs::exists(p)) continue;
    bsms::Json j = bsms::load_json_file(p.string());
    if (j.contains("rmse_per_step")) j.erase("rmse_per_step");
    std::cout << "  " << name << ":\n" << j.dump(2) << '\n';
  }
  std::cout << described;
}

// A checkpoint file by its name (RUN/checkpoints/*.h5) or its format attribute.
bool is_checkpoint_path(const std::string& path) {
  const fs::path p(path);
  return p.extension() == ".h5" && p.parent_path().filename() == "checkpoints";
}

void info(const std::string& path) {
  if (fs::is_directory(path)) {
    if (fs::exists(fs::path(path) / "config.json")) return info_run(path);
    if (fs::exists(fs::path(path) / "meta.json")) return info_meshgraphnets(path);
    // A bsms dataset folder (bsms generate): each split file. generate writes the three at once
    // (or none), so a folder with some of them is not a whole dataset (an interrupted copy, an
    // older bsms) and is refused rather than described.
    if (fs::exists(fs::path(path) / "generate.json")) {
      std::string missing;
      int present = 0;
      for (const char* split : {"train", "valid", "test"}) {
        if (fs::is_regular_file(fs::path(path) / (std::string(split) + ".h5")))
          ++present;
        else
          missing += (missing.empty() ? "" : ", ") + std::string(split) + ".h5";
      }
      if (present > 0 && present < 3)
        throw bsms::InputError(path + ": incomplete dataset: " + missing +
                               " missing (bsms generate writes all three splits or none; run "
                               "it again with the same settings to finish it)");
    }
    bool splits = false;
    for (const char* split : {"train", "valid", "test"}) {
      const fs::path file = fs::path(path) / (std::string(split) + ".h5");
      if (!fs::is_regular_file(file)) continue;
      info(file.string());
      splits = true;
    }
    if (splits) return;
    return info_dataset(path);  // public layout folder
  }
  if (fs::path(path).extension() == ".pt") {
    if (!fs::is_regular_file(path)) throw bsms::InputError(path + ": no such checkpoint");
    throw bsms::InputError(bsms::legacy_checkpoint_message(path));
  }
  if (is_checkpoint_path(path)) {
    std::cout << describe_checkpoint(path);
    return;
  }
  if (fs::path(path).extension() == ".tfrecord") {
    const fs::path parent = fs::path(path).parent_path();
    return info_meshgraphnets(parent.empty() ? "." : parent.string(),
                              fs::path(path).stem().string());
  }
  const bsms::H5File f(path, bsms::H5File::Mode::kRead);
  const std::string format = f.has_attr("/", "format") ? f.attr_string("/", "format") : "";
  if (format == "bsms-dataset") return info_dataset(path);
  if (format == bsms::kCheckpointFormat) {
    std::cout << describe_checkpoint(path);
    return;
  }
  if (format == "bsms-multilevel") return info_multilevel(f);
  if (format == "bsms-frames") return info_frames(f);
  if (f.exists("/mesh_pos")) return info_dataset(fs::path(path).parent_path().string());
  if (format.empty())
    for (const auto& name : f.list("/"))
      if (f.exists("/" + name + "/mesh_pos")) return info_dataset(path);  // single-file public
  throw bsms::InputError(
      path + ": unknown file (format attribute '" + format +
      "'; expected bsms-dataset, bsms-multilevel, bsms-frames or bsms-checkpoint)");
}

BSMS_COMMAND(
    "info", "summarise a dataset, multilevel graph file, frames file, run folder or checkpoint",
    [](CLI::App& sub) {
      auto path = std::make_shared<std::string>();
      sub.add_option("file", *path, "HDF5 file, run folder or checkpoint (.h5)")->required();
      sub.callback([path] { info(*path); });
    });

}  // namespace
