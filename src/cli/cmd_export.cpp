// bsms export INPUT --xdmf [--out DIR] [--trajectory i] [--split S]: XDMF descriptions so
// ParaView opens a dataset, a bsms file as it is, public data after conversion to bsms HDF5.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

#include "cli/command.hpp"
#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/dataset.hpp"
#include "data/dataset/xdmf.hpp"

namespace {

namespace fs = std::filesystem;

struct ExportArgs {
  std::string input;
  bool xdmf = false;
  std::string out;
  std::string split;
  int64_t trajectory = -1;
};

// One split to export and the name its outputs start with (the split, or the bsms file's stem).
struct Source {
  bsms::Dataset dataset;
  std::string name;
};

const char* const kSplits[] = {"train", "valid", "test"};

// The splits `input` holds, as `bsms info` reads it: a bsms dataset file or folder, a
// MeshGraphNets folder or one of its .tfrecord splits, a public folder of {i}.h5 (or one file of
// it: its folder), or a public single file.
std::vector<Source> open_sources(const ExportArgs& a) {
  const fs::path input(a.input);
  std::vector<Source> sources;
  auto wanted = [&](const std::string& split) { return a.split.empty() || a.split == split; };
  std::error_code ec;
  if (fs::is_directory(input, ec)) {
    const bool meshgraphnets = fs::exists(input / "meta.json", ec);
    for (const char* split : kSplits)
      if (wanted(split) && bsms::Dataset::has_split(a.input, split))
        sources.push_back({bsms::Dataset::open_split(a.input, split), split});
    if (!sources.empty()) return sources;
    if (meshgraphnets || !a.split.empty())
      throw bsms::InputError(
          a.input + ": no split " +
          (a.split.empty() ? std::string("train, valid or test") : "'" + a.split + "'") +
          (meshgraphnets ? " (.tfrecord beside meta.json)" : " ({split}.h5 or {split}/)"));
    fs::path normal = input.lexically_normal();
    if (normal.filename().empty()) normal = normal.parent_path();
    sources.push_back({bsms::Dataset(a.input), normal.filename().string()});
    return sources;
  }
  if (!a.split.empty())
    throw bsms::InputError("export: --split needs a dataset folder, not the file " + a.input);
  if (input.extension() == ".tfrecord") {
    const fs::path parent = input.parent_path().empty() ? fs::path(".") : input.parent_path();
    sources.push_back(
        {bsms::Dataset::open_split(parent.string(), input.stem().string()), input.stem().string()});
    return sources;
  }
  bool public_member = false;  // DIR/{i}.h5 of a public folder: the file has the mesh at its root
  {
    const bsms::H5File f(a.input, bsms::H5File::Mode::kRead);
    public_member = !f.has_attr("/", "format") && f.exists("/mesh_pos");
  }
  if (public_member) {
    const fs::path parent = input.parent_path().empty() ? fs::path(".") : input.parent_path();
    fs::path normal = fs::absolute(parent).lexically_normal();
    if (normal.filename().empty()) normal = normal.parent_path();
    sources.push_back({bsms::Dataset(parent.string()), normal.filename().string()});
    return sources;
  }
  sources.push_back({bsms::Dataset(a.input), input.stem().string()});
  return sources;
}

std::string indexed(const std::string& name, int64_t t, const char* extension) {
  char suffix[32];
  std::snprintf(suffix, sizeof suffix, "_%06lld%s", static_cast<long long>(t), extension);
  return name + suffix;
}

// Inputs are never written: refuses an output path that is an input file.
void check_not_input(const fs::path& output, const bsms::Dataset& d) {
  std::error_code ec;
  if (fs::exists(output, ec) && fs::equivalent(output, d.location(), ec))
    throw bsms::InputError(output.string() + ": is the input; choose another --out folder");
}

// Trajectory `t` of public data as a one-trajectory bsms dataset file.
void convert(const bsms::Dataset& d, int64_t t, const std::string& path) {
  bsms::Trajectory trajectory;
  trajectory.mesh = d.mesh(t);
  trajectory.num_frames = d.num_frames(t);
  trajectory.parameters = bsms::Json{
      {"source", d.location()},
      {"source_layout", bsms::layout_name(d.layout())},
      {"source_trajectory",
       t}}.dump();
  for (const auto& field : d.fields())
    trajectory.fields[field.name] = d.read(t, field.name, 0, trajectory.num_frames);
  bsms::DatasetWriter writer(path, d.scene(), d.dim(), d.frame_dt());
  writer.add(trajectory);
  writer.commit();
}

void run_export(const ExportArgs& a) {
  if (!a.xdmf) throw bsms::InputError("export: choose a format (--xdmf)");
  std::vector<Source> sources = open_sources(a);
  for (const auto& s : sources) {
    const bsms::Dataset& d = s.dataset;
    if (a.trajectory >= d.num_trajectories())
      throw bsms::InputError(d.location() + ": --trajectory " + std::to_string(a.trajectory) +
                             " out of range 0.." + std::to_string(d.num_trajectories() - 1));
    if (!d.is_public_layout()) continue;
    if (a.out.empty())
      throw bsms::InputError(d.location() + ": public data (" + bsms::layout_name(d.layout()) +
                             ") is converted to bsms HDF5 for XDMF: give --out DIR, a writable "
                             "folder for it");
    std::error_code ec;
    if (d.layout() == bsms::DatasetLayout::kPublicFolder && fs::exists(a.out, ec) &&
        fs::equivalent(a.out, d.location(), ec))
      throw bsms::InputError(a.out +
                             ": --out is the public folder itself (it may hold only "
                             "{i}.h5 files); choose another folder");
  }
  std::optional<bsms::cli::RemoveOnFailure> cleanup;
  if (!a.out.empty()) {
    bsms::cli::require_creatable_dir(a.out);
    cleanup.emplace(a.out);
    std::error_code ec;
    fs::create_directories(a.out, ec);
    if (!fs::is_directory(a.out, ec))
      throw bsms::IoError(a.out + ": cannot create the output folder");
  }
  for (const auto& s : sources) {
    const bsms::Dataset& d = s.dataset;
    const fs::path dir = !a.out.empty() ? fs::path(a.out) : fs::path(d.location()).parent_path();
    const int64_t first = a.trajectory >= 0 ? a.trajectory : 0;
    const int64_t last = a.trajectory >= 0 ? a.trajectory + 1 : d.num_trajectories();
    for (int64_t t = first; t < last; ++t) {
      const fs::path xdmf = dir / indexed(s.name, t, ".xdmf");
      check_not_input(xdmf, d);
      check_not_input(bsms::xdmf_views_path(xdmf.string()), d);
      if (d.is_public_layout()) {
        const fs::path converted = dir / indexed(s.name, t, ".h5");
        check_not_input(converted, d);
        convert(d, t, converted.string());
        bsms::write_trajectory_xdmf(bsms::Dataset(converted.string()), 0, xdmf.string());
      } else {
        bsms::write_trajectory_xdmf(d, t, xdmf.string());
      }
      std::cout << xdmf.string() << '\n';
    }
  }
}

BSMS_COMMAND(
    "export", "export a dataset for viewing in ParaView (XDMF, reading the HDF5 data in place)",
    [](CLI::App& sub) {
      auto a = std::make_shared<ExportArgs>();
      sub.footer(
          "A bsms dataset file FILE gets OUT/STEM_<trajectory>.xdmf (OUT: --out, default FILE's "
          "folder)\nwith OUT/STEM_<trajectory>.xdmf.h5, per-frame views of FILE that copy no "
          "data; open the\n.xdmf in ParaView with any XDMF reader. Public data (a MeshGraphNets "
          "folder or .tfrecord, a\nfolder of {i}.h5, a single-file {split}.h5) may be "
          "read-only and is never written: --out is\nrequired, and each trajectory is converted "
          "to OUT/SPLIT_<trajectory>.h5 (bsms layout) first.");
      sub.add_option("input", a->input,
                     "bsms dataset file (e.g. DIR/train.h5) or folder, or public data "
                     "(as bsms info reads it)")
          ->required();
      sub.add_flag("--xdmf", a->xdmf, "write XDMF (one file per trajectory) for ParaView");
      sub.add_option("--out", a->out,
                     "output folder (default: beside a bsms file; required for public data)");
      sub.add_option("--split", a->split, "of a dataset folder, only this split (default all)");
      sub.add_option("--trajectory", a->trajectory, "only this trajectory (default all)")
          ->check(CLI::NonNegativeNumber);
      sub.callback([a] { run_export(*a); });
    });

}  // namespace
