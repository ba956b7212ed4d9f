#include "pipeline/run_files.hpp"

#include <cstdlib>
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

void write_text_atomic(const std::string& path, const std::string& text) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path());
    f << text;
    if (!f) throw IoError(path + ": cannot write");
  }
  out.commit();
}

std::string gnuplot_quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("''") : std::string(1, c);
  return q + "'";
}

void run_gnuplot(const std::string& script) {
  const std::string cmd = "gnuplot '" + script + "' 2>'" + script + ".log'";
  if (std::system(cmd.c_str()) != 0)
    throw IoError(script + ": gnuplot failed (see " + script + ".log)");
}

}  // namespace bsms
