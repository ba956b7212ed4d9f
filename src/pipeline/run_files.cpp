#include "pipeline/run_files.hpp"

#include <filesystem>
#include <fstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "pipeline/trainer.hpp"

namespace bsms {

void write_json_atomic(const std::string& path, const Json& value) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path());
    f << value.dump(2) << '\n';
    if (!f) throw IoError(path + ": cannot write");
  }
  out.commit();
}

void write_text_atomic(const std::string& path, const std::string& text) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path());
    f << text;
    if (!f) throw IoError(path + ": cannot write");
  }
  out.commit();
}

RunFolder RunFolder::open(const std::string& dir) {
  RunFolder run;
  run.dir = dir;
  run.config_path = run_config_path(dir);
  if (!std::filesystem::exists(run.config_path))
    throw InputError(dir + ": not a run folder (no config.json; train first with bsms train)");
  const Json saved = load_json_file(run.config_path);
  for (const char* key : {"config", "features_resolved", "levels"})
    if (!saved.contains(key))
      throw InputError(run.config_path + ": key " + key + " is missing (written by bsms train)");
  if (!saved["levels"].is_number_integer() || saved["levels"].get<int64_t>() < 1)
    throw InputError(run.config_path + ": levels = " + saved["levels"].dump() +
                     ", expected an integer >= 1");
  run.config = parse_train_config(saved["config"], run.config_path);
  run.levels = saved["levels"].get<int>();
  run.features_resolved = saved["features_resolved"];
  return run;
}

std::string RunFolder::label() const {
  return std::filesystem::path(dir).filename().string() + " (" + config.model.type + ")";
}

}  // namespace bsms
