// Small JSON files of a run folder, written atomically.
#pragma once

#include <string>

#include "core/config.hpp"

namespace bsms {

void write_json_atomic(const std::string& path, const Json& value);

}  // namespace bsms
