// Small files of a run or report folder, written atomically, and plotting with gnuplot.
#pragma once

#include <string>

#include "core/config.hpp"

namespace bsms {

void write_json_atomic(const std::string& path, const Json& value);
void write_text_atomic(const std::string& path, const std::string& text);

// Runs gnuplot (a Debian package the Makefile installs) on a script file; its messages go to
// SCRIPT.log and an IoError names the script when gnuplot fails.
void run_gnuplot(const std::string& script);

// A gnuplot single-quoted string (a quote inside is doubled).
std::string gnuplot_quoted(const std::string& s);

}  // namespace bsms
