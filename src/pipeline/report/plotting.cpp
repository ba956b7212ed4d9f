#include "pipeline/report/plotting.hpp"

#include <cstdlib>
#include <iostream>

#include "core/error.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {

std::string gnuplot_quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("''") : std::string(1, c);
  return q + "'";
}

std::string gnuplot_png_preamble(const std::string& png, int width, int height) {
  return "set terminal pngcairo size " + std::to_string(width) + "," + std::to_string(height) +
         " font ',11' noenhanced\nset output " + gnuplot_quoted(png) + "\n";
}

std::string gnuplot_gif_preamble(const std::string& gif, int width, int height, int delay_cs) {
  return "set terminal gif animate delay " + std::to_string(delay_cs) + " loop 0 optimize size " +
         std::to_string(width) + "," + std::to_string(height) + " noenhanced\nset output " +
         gnuplot_quoted(gif) + "\n";
}

bool gnuplot_available() {
  static const bool available = std::system("command -v gnuplot >/dev/null 2>&1") == 0;
  return available;
}

bool draw_plot(const std::string& script, const std::string& script_text) {
  write_text_atomic(script, script_text);
  if (!gnuplot_available()) {
    static bool warned = false;
    if (!warned) {
      warned = true;
      std::cerr << "bsms: warning: gnuplot not found (make deps installs it): plots skipped, "
                   "their scripts kept (first: "
                << script << ")\n";
    }
    return false;
  }
  const std::string cmd =
      "gnuplot " + gnuplot_quoted(script) + " 2>" + gnuplot_quoted(script + ".log");
  if (std::system(cmd.c_str()) != 0)
    throw IoError(script + ": gnuplot failed (see " + script + ".log)");
  return true;
}

}  // namespace bsms
