#include "pipeline/adapters/run_adapter.hpp"

#include "pipeline/adapters/eulerian.hpp"
#include "pipeline/adapters/lagrangian.hpp"

namespace bsms {

std::unique_ptr<DomainAdapter> adapter_from_features(const Json& features,
                                                     const std::string& file) {
  if (features.is_object() && features.value("kind", std::string()) == "eulerian")
    return std::make_unique<EulerianAdapter>(eulerian_spec_from_json(features, file));
  return std::make_unique<LagrangianAdapter>(lagrangian_spec_from_json(features, file));
}

}  // namespace bsms
