#include "pipeline/runs/train_stats.hpp"

#include <filesystem>

#include "core/error.hpp"
#include "pipeline/runs/json_measures.hpp"

namespace bsms {

Json to_json(const TrainStats& s) {
  Json j = {{"steps", s.steps},
            {"train_ms_per_step", s.train_ms_per_step},
            {"peak_rss_mb_train", s.peak_rss_mb_train},
            {"threads", s.threads},
            {"world_size", s.world_size},
            {"samples_per_step", s.samples_per_step},
            {"wall_s", s.wall_s},
            {"final_loss", measure_json(s.final_loss)},
            {"final_valid_loss", measure_json(s.final_valid_loss)},
            {"final_valid_zero_prediction", measure_json(s.final_valid_zero_prediction)},
            {"num_parameters", s.num_parameters},
            {"valid_split", s.valid_split}};
  if (!s.blas.empty()) j["blas"] = s.blas;
  if (!s.matmul.empty()) j["matmul"] = s.matmul;
  if (!s.allocator.empty()) j["allocator"] = s.allocator;
  if (s.allreduce_ms_per_step) j["allreduce_ms_per_step"] = *s.allreduce_ms_per_step;
  if (s.allreduce_calls_per_step) j["allreduce_calls_per_step"] = *s.allreduce_calls_per_step;
  if (s.seconds_to_first_step) j["seconds_to_first_step"] = *s.seconds_to_first_step;
  if (s.graphs_made) j["graphs_made"] = *s.graphs_made;
  if (s.graphs_evicted) j["graphs_evicted"] = *s.graphs_evicted;
  if (s.graph_cache_peak_mb) j["graph_cache_peak_mb"] = *s.graph_cache_peak_mb;
  if (s.best_step) j["best_step"] = *s.best_step;
  if (s.best_valid_rollout_rmse) j["best_valid_rollout_rmse"] = *s.best_valid_rollout_rmse;
  return j;
}

TrainStats train_stats_from_json(const Json& json, const std::string& file) {
  require(json.is_object(), {file, ""}, "a JSON object");
  JsonObjectReader r(json, {file, ""});
  TrainStats s;
  s.steps = read_int_at_least<int64_t>(r, "steps", 0);
  s.train_ms_per_step = read_at_least(r, "train_ms_per_step");
  s.peak_rss_mb_train = read_at_least(r, "peak_rss_mb_train");
  s.threads = read_int_at_least<int>(r, "threads", 1);
  s.world_size = read_int_at_least<int>(r, "world_size", 1);
  s.samples_per_step = read_int_at_least<int64_t>(r, "samples_per_step", 1);
  s.wall_s = read_at_least(r, "wall_s");
  s.final_loss = read_measure(r, "final_loss");
  s.final_valid_loss = read_measure(r, "final_valid_loss");
  s.final_valid_zero_prediction = read_measure(r, "final_valid_zero_prediction");
  s.num_parameters = read_int_at_least<int64_t>(r, "num_parameters", 0);
  s.valid_split = r.get<std::string>("valid_split");
  require(s.valid_split == "valid" || s.valid_split == "train", r.context("valid_split"),
          "\"valid\" or \"train\"");
  if (r.has("blas")) s.blas = r.get<std::string>("blas");
  if (r.has("matmul")) s.matmul = r.get<std::string>("matmul");
  if (r.has("allocator")) s.allocator = r.get<std::string>("allocator");
  if (r.has("allreduce_ms_per_step"))
    s.allreduce_ms_per_step = read_at_least(r, "allreduce_ms_per_step");
  if (r.has("allreduce_calls_per_step"))
    s.allreduce_calls_per_step = read_at_least(r, "allreduce_calls_per_step");
  if (r.has("seconds_to_first_step"))
    s.seconds_to_first_step = read_at_least(r, "seconds_to_first_step");
  if (r.has("graphs_made")) s.graphs_made = read_int_at_least<int64_t>(r, "graphs_made", 0);
  if (r.has("graphs_evicted"))
    s.graphs_evicted = read_int_at_least<int64_t>(r, "graphs_evicted", 0);
  if (r.has("graph_cache_peak_mb")) s.graph_cache_peak_mb = read_at_least(r, "graph_cache_peak_mb");
  if (r.has("best_step")) s.best_step = read_int_at_least<int64_t>(r, "best_step", 0);
  if (r.has("best_valid_rollout_rmse"))
    s.best_valid_rollout_rmse = read_at_least(r, "best_valid_rollout_rmse");
  r.finish();
  return s;
}

TrainStats read_train_stats(const std::string& file) {
  if (!std::filesystem::exists(file))
    throw InputError(file + ": not found (written by bsms train when a session ends)");
  return train_stats_from_json(load_json_file(file, "training stats"), file);
}

}  // namespace bsms
