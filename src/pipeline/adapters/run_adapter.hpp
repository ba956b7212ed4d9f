// The domain adapter of a trained run (adapter.hpp), from what its config.json keeps.
#pragma once

#include <memory>
#include <string>

#include "core/config.hpp"
#include "pipeline/adapters/adapter.hpp"

namespace bsms {

// The adapter of a trained run from its features_resolved (`file`: the run's config.json, for
// errors): Lagrangian or Eulerian by the features' "kind" (Lagrangian when it has none).
std::unique_ptr<DomainAdapter> adapter_from_features(const Json& features, const std::string& file);

}  // namespace bsms
