#include "pipeline/run_files.hpp"

#include <fstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"

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

}  // namespace bsms
