// The multilevel graph file (docs/design.md "Multilevel graph file"): written atomically, read back
// with every shape and graph invariant checked.
#pragma once

#include <string>

#include "preprocess/multilevel_graph.hpp"

namespace bsms {

inline constexpr const char* kMultilevelFormat = "bsms-multilevel";
inline constexpr int64_t kMultilevelVersion = 1;

// Writes `graph` to `path` through a temporary file renamed into place (never a partial file).
// Positions and node weights are not stored. Throws IoError (InputError for an unusable folder).
void write_multilevel_graph(const MultilevelGraph& graph, const std::string& path);

// Reads and validates a file: format, version, seeding, level count, dataset shapes, edges sorted,
// symmetric, in range and without self loops, pooled ascending and in range, finite weights.
// Throws InputError naming the file and the dataset or attribute at fault.
MultilevelGraph read_multilevel_graph(const std::string& path);

}  // namespace bsms
