// bsms info FILE|RUN: summarises a dataset (bsms, public HDF5 layouts, a MeshGraphNets folder or
// one of its .tfrecord splits), a multilevel graph file, simulation frames, a run or a training
// checkpoint (.pt).
#include <torch/serialize/input-archive.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>

#include "cli/command.hpp"
#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/dataset.hpp"
#include "data/dataset/tfrecord.hpp"

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

// Digest of the entries of a torch archive: names, types, shapes and bytes (FNV-1a, 64 bits), so
// that two checkpoints can be compared bit for bit (e.g. a resumed run with an uninterrupted one).
struct ArchiveDigest {
  int64_t tensors = 0;
  int64_t values = 0;  // tensor elements
  uint64_t hash = 0xcbf29ce484222325ull;
  void add(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) hash = (hash ^ p[i]) * 0x100000001b3ull;
  }
  void add(const std::string& text) { add(text.data(), text.size() + 1); }
};

// `names` renames keys and string values: the optimizer's archive names parameters by their
// address in memory, which differs from process to process, the digest by their position.
using Names = std::map<std::string, std::string>;
void digest_archive(torch::serialize::InputArchive& archive, const std::string& prefix,
                    const std::vector<std::string>& skip, const Names& names, ArchiveDigest& d) {
  auto named = [&](const std::string& s) {
    const auto it = names.find(s);
    return it == names.end() ? s : it->second;
  };
  std::vector<std::pair<std::string, std::string>> keys;  // (digested name, key)
  for (const auto& key : archive.keys())
    if (std::find(skip.begin(), skip.end(), key) == skip.end()) keys.emplace_back(named(key), key);
  std::sort(keys.begin(), keys.end());
  for (const auto& [name, key] : keys) {
    c10::IValue value;
    archive.read(key, value);
    d.add(prefix + name);
    if (value.isObject()) {
      torch::serialize::InputArchive sub;
      archive.read(key, sub);
      digest_archive(sub, prefix + name + ".", {}, names, d);
    } else if (value.isString()) {
      d.add(named(value.toStringRef()));
    } else if (value.isTensor()) {
      const at::Tensor t = value.toTensor().contiguous().cpu();
      d.add(std::string(c10::toString(t.scalar_type())));
      for (int64_t size : t.sizes()) d.add(&size, sizeof size);
      d.add(t.data_ptr(), t.nbytes());
      ++d.tensors;
      d.values += t.numel();
    } else if (value.isDouble()) {
      const double x = value.toDouble();
      d.add(&x, sizeof x);
    } else if (value.isInt()) {
      const int64_t x = value.toInt();
      d.add(&x, sizeof x);
    } else {
      std::ostringstream text;
      text << value;
      d.add(text.str());
    }
  }
}

// torch::optim's layout: param_groups/G holds entries params/I, the address naming parameter I
// of group G (the key of its state): names each address by that path.
void parameter_names(torch::serialize::InputArchive& archive, const std::string& prefix,
                     Names& names) {
  for (const auto& key : archive.keys()) {
    c10::IValue value;
    archive.read(key, value);
    if (value.isObject()) {
      torch::serialize::InputArchive sub;
      archive.read(key, sub);
      parameter_names(sub, prefix + key + ".", names);
    } else if (value.isString() && key.rfind("params/", 0) == 0) {
      names[value.toStringRef()] = prefix + key;
    }
  }
}

std::string hex(uint64_t h) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
  return text;
}

// A training checkpoint (or a module archive): step, losses, and digests of the model's and the
// optimizer's state.
void info_checkpoint(const std::string& path, const std::string& indent = "") {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const c10::Error&) {
    throw bsms::InputError(path + ": not a readable checkpoint (truncated or corrupt)");
  }
  auto scalar = [&](const char* key, int64_t i) {
    torch::Tensor t;
    return archive.try_read(key, t) && t.numel() > i ? t.reshape({-1})[i].item<double>()
                                                     : std::nan("");
  };
  const std::vector<std::string> state = {"optimizer", "step", "wall_s", "losses"};
  ArchiveDigest model, optimizer;
  try {
    digest_archive(archive, "", state, {}, model);
    torch::serialize::InputArchive sub;
    if (archive.try_read("optimizer", sub)) {
      Names names;
      parameter_names(sub, "", names);
      digest_archive(sub, "", {}, names, optimizer);
    }
  } catch (const c10::Error& e) {
    const std::string what = e.what_without_backtrace();
    throw bsms::InputError(path + ": unreadable entry (" + what.substr(0, what.find('\n')) + ")");
  }
  const double step = scalar("step", 0);
  std::cout << indent << path << ": bsms " << (std::isnan(step) ? "module" : "training")
            << " checkpoint\n";
  if (!std::isnan(step)) {
    std::cout << indent << "  step " << static_cast<int64_t>(step) << ", wall time "
              << scalar("wall_s", 0) << " s";
    if (!std::isnan(scalar("losses", 0)))
      std::cout << ", loss " << scalar("losses", 0) << ", valid loss " << scalar("losses", 1)
                << " (zero prediction " << scalar("losses", 2) << ")";
    std::cout << '\n';
  }
  std::cout << indent << "  model: " << model.tensors << " tensors, " << model.values
            << " values, digest " << hex(model.hash) << '\n';
  if (optimizer.tensors > 0 || !std::isnan(step))
    std::cout << indent << "  optimizer: " << optimizer.tensors << " tensors, " << optimizer.values
              << " values, digest " << hex(optimizer.hash) << '\n';
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
  const fs::path checkpoint = fs::path(run) / "checkpoints" / "latest.pt";
  if (fs::exists(checkpoint)) {
    try {
      info_checkpoint(checkpoint.string(), "  ");
    } catch (const bsms::InputError& e) {
      std::cout << "  " << e.what() << '\n';
    }
  }
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
    return info_checkpoint(path);
  }
  if (fs::path(path).extension() == ".tfrecord") {
    const fs::path parent = fs::path(path).parent_path();
    return info_meshgraphnets(parent.empty() ? "." : parent.string(),
                              fs::path(path).stem().string());
  }
  const bsms::H5File f(path, bsms::H5File::Mode::kRead);
  const std::string format = f.has_attr("/", "format") ? f.attr_string("/", "format") : "";
  if (format == "bsms-dataset") return info_dataset(path);
  if (format == "bsms-multilevel") return info_multilevel(f);
  if (format == "bsms-frames") return info_frames(f);
  if (f.exists("/mesh_pos")) return info_dataset(fs::path(path).parent_path().string());
  if (format.empty())
    for (const auto& name : f.list("/"))
      if (f.exists("/" + name + "/mesh_pos")) return info_dataset(path);  // single-file public
  throw bsms::InputError(path + ": unknown file (format attribute '" + format +
                         "'; expected bsms-dataset, bsms-multilevel or bsms-frames)");
}

BSMS_COMMAND(
    "info", "summarise a dataset, multilevel graph file, frames file, run folder or checkpoint",
    [](CLI::App& sub) {
      auto path = std::make_shared<std::string>();
      sub.add_option("file", *path, "HDF5 file, run folder or checkpoint (.pt)")->required();
      sub.callback([path] { info(*path); });
    });

}  // namespace
