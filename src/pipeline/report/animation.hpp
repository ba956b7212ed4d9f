// Animated GIFs of a rollout: prediction over ground truth at every frame, drawn by gnuplot.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "data/dataset/dataset.hpp"

namespace bsms {

// The mesh edges an animation draws, as node pairs: every edge of a 2-D mesh; for a 3-D mesh
// (tetrahedra) the edges of its boundary triangles, the faces that belong to one cell only, so
// that the surface stays readable. Each edge once, (a, b) with a < b, sorted.
std::vector<std::pair<int32_t, int32_t>> drawn_edges(const TrajectoryMesh& mesh);

// Root mean square over nodes of the distance between two frames of positions, [N, dim] each.
double rms_distance(const std::vector<float>& a, const std::vector<float>& b, int dim);

// Writes PLOTS/NAME.gif: trajectory 0 of a rollout file (predicted `world_pos` and its
// `target_world_pos`), every frame, truth in grey and prediction in red, each frame titled with
// its number and that frame's RMS node distance. 2-D meshes are drawn in the plane, 3-D meshes
// in a fixed perspective view; the axes hold the truth's extent over the whole rollout so that
// the picture does not jump. The data and the gnuplot script stay beside it. Returns whether the
// GIF was drawn (false without gnuplot, as for every plot: plotting.hpp).
bool animate_rollout(const Dataset& rollout, const std::string& plots, const std::string& name,
                     const std::string& title);

}  // namespace bsms
