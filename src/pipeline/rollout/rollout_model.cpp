#include "pipeline/rollout/rollout_model.hpp"

#include <filesystem>

#include "core/error.hpp"
#include "pipeline/adapters/scene_features.hpp"

namespace bsms {

RolloutModel open_rollout_model(const RunFolder& folder, const Dataset& data,
                                const std::string& data_dir, const std::string& seeding,
                                const std::string& checkpoint) {
  namespace fs = std::filesystem;
  RolloutModel m;
  m.model_type = folder.config.model.type;
  m.spec = walls_for_scene(lagrangian_spec_from_json(folder.features_resolved, folder.config_path),
                           data.parsed_scene());
  m.adapter = std::make_unique<LagrangianAdapter>(m.spec);
  m.simulator = std::make_shared<LearnedSimulator>(m.adapter->model_shape(), folder.config.model,
                                                   folder.levels);
  const ModelCheckpoint chosen = run_model_checkpoint(folder.dir, checkpoint);
  m.checkpoint = chosen.name;
  m.checkpoint_step = load_checkpoint(chosen.path, *m.simulator, nullptr).step;
  m.simulator->eval();
  const std::vector<std::string> cache_dirs = multilevel_cache_dirs(data_dir, folder.dir);
  std::error_code ec;
  for (const auto& d : cache_dirs) fs::create_directories(d, ec);
  m.seeding = seeding.empty() ? folder.config.model.seeding : parse_seeding(seeding);
  m.store = std::make_unique<GraphStore>(m.seeding, folder.levels, cache_dirs);
  return m;
}

torch::Tensor predict_step(RolloutModel& model, const TrajectoryMesh& mesh,
                           const std::vector<torch::Tensor>& frames,
                           const torch::Tensor& prescribed) {
  const int64_t count = static_cast<int64_t>(frames.size());
  if (count < 2) throw InputError("predict: needs the positions of at least 2 frames");
  const int64_t t = count - 1;
  FrameState state{model.store->get(mesh).get(), &mesh, frames[t - 1], frames[t], prescribed, {}};
  for (int64_t k = t - 2; k >= 0 && k > t - 1 - model.spec.history; --k)
    state.older.push_back(frames[k]);
  const Batch batch = model.adapter->make_batch({state});
  return model.adapter->integrate(batch, model.simulator->predict(batch), prescribed);
}

}  // namespace bsms
