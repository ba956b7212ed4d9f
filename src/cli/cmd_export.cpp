// bsms export FILE --xdmf [--trajectory i]: XDMF descriptions so ParaView opens a dataset.
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "cli/command.hpp"
#include "core/error.hpp"
#include "data/dataset/dataset.hpp"
#include "data/dataset/xdmf.hpp"

namespace {

namespace fs = std::filesystem;

struct ExportArgs {
  std::string file;
  bool xdmf = false;
  int64_t trajectory = -1;
};

void run_export(const ExportArgs& a) {
  if (!a.xdmf) throw bsms::InputError("export: choose a format (--xdmf)");
  const bsms::Dataset d(a.file);
  if (a.trajectory >= d.num_trajectories())
    throw bsms::InputError(a.file + ": --trajectory " + std::to_string(a.trajectory) +
                           " out of range 0.." + std::to_string(d.num_trajectories() - 1));
  const fs::path base = fs::path(a.file).parent_path() / fs::path(a.file).stem();
  const int64_t first = a.trajectory >= 0 ? a.trajectory : 0;
  const int64_t last = a.trajectory >= 0 ? a.trajectory + 1 : d.num_trajectories();
  for (int64_t t = first; t < last; ++t) {
    char suffix[32];
    std::snprintf(suffix, sizeof suffix, "_%06lld.xdmf", static_cast<long long>(t));
    const std::string out = base.string() + suffix;
    bsms::write_trajectory_xdmf(d, t, out);
    std::cout << out << '\n';
  }
}

BSMS_COMMAND("export", "export a dataset for viewing (XDMF beside the HDF5 file, for ParaView)",
             [](CLI::App& sub) {
               auto a = std::make_shared<ExportArgs>();
               sub.add_option("file", a->file, "bsms dataset file (e.g. DIR/train.h5)")->required();
               sub.add_flag("--xdmf", a->xdmf, "write FILE_<trajectory>.xdmf beside FILE");
               sub.add_option("--trajectory", a->trajectory, "only this trajectory (default all)")
                   ->check(CLI::NonNegativeNumber);
               sub.callback([a] { run_export(*a); });
             });

}  // namespace
