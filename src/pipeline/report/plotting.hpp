// Every PNG plot of bsms (report, experiments) is a gnuplot script written beside its data and
// run through one function, with one policy for a machine without gnuplot.
#pragma once

#include <string>

namespace bsms {

// The first lines of every script: the pngcairo terminal (width × height pixels, 11 pt font,
// labels printed as given) and the output file `png`.
std::string gnuplot_png_preamble(const std::string& png, int width = 900, int height = 560);

// The same for an animated GIF (gnuplot's gif terminal: every plot command adds a frame, shown
// for `delay_cs` hundredths of a second; the animation loops).
std::string gnuplot_gif_preamble(const std::string& gif, int width, int height, int delay_cs = 8);

// A gnuplot single-quoted string (a quote inside is doubled).
std::string gnuplot_quoted(const std::string& s);

// Whether `gnuplot` is on the PATH (looked up once per process).
bool gnuplot_available();

// Writes `script_text` to `script` (atomically) and runs gnuplot on it; its messages go to
// SCRIPT.log. The policy for all plots: without gnuplot (`make deps` installs it) the script and
// its data stay for later, one warning line per process says plots were skipped, and the result is
// false; a gnuplot that fails on the script is an IoError naming it. True when the PNG was drawn.
bool draw_plot(const std::string& script, const std::string& script_text);

}  // namespace bsms
