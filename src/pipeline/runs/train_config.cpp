#include "pipeline/runs/train_config.hpp"

#include <algorithm>
#include <cmath>

namespace bsms {

namespace {

// Keys of the top level besides the sections.
void parse_run_keys(JsonObjectReader& top, TrainConfig& c) {
  c.data = top.get<std::string>("data");
  c.steps = top.get<int64_t>("steps");
  require(c.steps >= 1, top.context("steps"), "a positive integer");
  c.time_budget_s = top.opt<double>("time_budget_s", c.time_budget_s);
  require(c.time_budget_s >= 0, top.context("time_budget_s"), ">= 0 (0 = no budget)");
  c.valid_every = top.opt<int64_t>("valid_every", c.valid_every);
  require(c.valid_every >= 1, top.context("valid_every"), "a positive integer");
  c.valid_samples = top.opt<int>("valid_samples", c.valid_samples);
  require(c.valid_samples >= 1, top.context("valid_samples"), "a positive integer");
  c.valid_rollout_every = top.opt<int64_t>("valid_rollout_every", c.valid_rollout_every);
  require(c.valid_rollout_every >= 0 && c.valid_rollout_every % c.valid_every == 0,
          top.context("valid_rollout_every"),
          "0 (off) or a positive multiple of valid_every (" + std::to_string(c.valid_every) +
              "): the rollouts score checkpoints");
  c.valid_rollout_trajectories =
      top.opt<int>("valid_rollout_trajectories", c.valid_rollout_trajectories);
  require(c.valid_rollout_trajectories >= 1, top.context("valid_rollout_trajectories"),
          "a positive integer");
  c.normalizer_steps = top.opt<int64_t>("normalizer_steps", c.normalizer_steps);
  require(c.normalizer_steps >= 1, top.context("normalizer_steps"), "a positive integer");
  c.seed = top.opt<uint64_t>("seed", c.seed);
  c.graph_cache_mb = top.opt<int64_t>("graph_cache_mb", c.graph_cache_mb);
  require(c.graph_cache_mb >= 0, top.context("graph_cache_mb"), ">= 0 (0 = no cap)");
}

// "levels": "auto" (0) or a count.
// A key whose automatic value the data decides: the string "auto" (returned as `automatic`, the
// internal sentinel) or a number `valid` accepts; any other value names the key and `expected`.
template <typename T, typename Valid>
T auto_or_number(JsonObjectReader& r, const std::string& key, T current, T automatic, Valid valid,
                 const std::string& expected) {
  if (!r.has(key)) return current;
  if (r.raw(key).is_string()) {
    require(r.raw(key).get<std::string>() == "auto", r.context(key), expected);
    return automatic;
  }
  const T value = r.get<T>(key);
  require(valid(value), r.context(key), expected);
  return value;
}

void parse_levels(JsonObjectReader& m, ModelConfig& model) {
  model.levels = auto_or_number<int>(
      m, "levels", 0, 0, [](int v) { return v >= 1 && v <= 64; },
      "\"auto\" or an integer in 1..64");
}

// "mp_per_level": one block count for every level, or a list of them, one per level.
void parse_mp_per_level(JsonObjectReader& m, ModelConfig& model) {
  if (m.has("mp_per_level") && m.raw("mp_per_level").is_array()) {
    const Json& list = m.raw("mp_per_level");
    bool ok = !list.empty() && list.size() <= 64;
    for (const auto& v : list) {
      ok = ok && v.is_number_integer() && v.get<int64_t>() >= 1 && v.get<int64_t>() <= 16;
      if (ok) model.mp_per_level_list.push_back(v.get<int>());
    }
    require(ok, m.context("mp_per_level"),
            "an integer in 1..16 or a list of them, one per level from the mesh down");
    if (model.levels > 0)
      require(static_cast<int>(list.size()) == model.levels, m.context("mp_per_level"),
              "one block count per level (" + std::to_string(model.levels) + " levels)");
    model.mp_per_level =
        *std::max_element(model.mp_per_level_list.begin(), model.mp_per_level_list.end());
  } else {
    model.mp_per_level = m.opt<int>("mp_per_level", model.mp_per_level);
    require(model.mp_per_level >= 1 && model.mp_per_level <= 16, m.context("mp_per_level"),
            "in 1..16");
  }
}

void parse_model(const Json& j, const JsonContext& ctx, ModelConfig& model) {
  JsonObjectReader m(j, ctx);
  model.type = m.opt<std::string>("type", model.type);
  require(model.type == "bsms" || model.type == "mgn", m.context("type"), "\"bsms\" or \"mgn\"");
  model.latent = m.opt<int64_t>("latent", model.latent);
  require(model.latent >= 1 && model.latent <= 4096, m.context("latent"), "in 1..4096");
  parse_levels(m, model);
  const std::string seeding = m.opt<std::string>("seeding", to_string(model.seeding));
  try {
    model.seeding = parse_seeding(seeding);
  } catch (const InputError&) {
    require(false, m.context("seeding"), "one of minave, closecenter, random");
  }
  model.message_passing_steps = m.opt<int>("message_passing_steps", model.message_passing_steps);
  require(model.message_passing_steps >= 1 && model.message_passing_steps <= 100,
          m.context("message_passing_steps"), "in 1..100");
  parse_mp_per_level(m, model);
  model.precision = m.opt<std::string>("precision", model.precision);
  require(model.precision == "float32" || model.precision == "bf16", m.context("precision"),
          "\"float32\" or \"bf16\"");
  model.edge_normalizer = m.opt<std::string>("edge_normalizer", model.edge_normalizer);
  require(model.edge_normalizer == "on" || model.edge_normalizer == "off",
          m.context("edge_normalizer"), "\"on\" or \"off\"");
  m.finish();
}

// The inputs and outputs of the model: strain, node types, walls, momentum, output, stress,
// statistics, kinematic and velocity inputs.
void parse_feature_channels(JsonObjectReader& f, FeatureConfig& features) {
  features.strain = f.opt<std::string>("strain", features.strain);
  require(features.strain == "auto" || features.strain == "off", f.context("strain"),
          "\"auto\" or \"off\"");
  features.num_node_types = auto_or_number<int>(
      f, "num_node_types", features.num_node_types, 0, [](int v) { return v >= 1 && v <= 64; },
      "\"auto\" or an integer in 1..64");
  features.walls = f.opt<std::string>("walls", features.walls);
  require(features.walls == "auto" || features.walls == "off", f.context("walls"),
          "\"auto\" or \"off\"");
  features.momentum = f.opt<std::string>("momentum", features.momentum);
  require(features.momentum == "auto" || features.momentum == "free" || features.momentum == "off",
          f.context("momentum"), "\"auto\", \"free\" or \"off\"");
  features.output = f.opt<std::string>("output", features.output);
  require(features.output == "auto" || features.output == "acceleration" ||
              features.output == "velocity",
          f.context("output"), "\"auto\", \"acceleration\" or \"velocity\"");
  features.stress = f.opt<std::string>("stress", features.stress);
  require(features.stress == "auto" || features.stress == "off", f.context("stress"),
          "\"auto\" or \"off\"");
  features.output_statistics = f.opt<std::string>("output_statistics", features.output_statistics);
  require(features.output_statistics == "auto" || features.output_statistics == "all" ||
              features.output_statistics == "predicted",
          f.context("output_statistics"), "\"auto\", \"all\" or \"predicted\"");
  features.kinematic_input = f.opt<std::string>("kinematic_input", features.kinematic_input);
  require(features.kinematic_input == "auto" || features.kinematic_input == "on" ||
              features.kinematic_input == "off",
          f.context("kinematic_input"), "\"auto\", \"on\" or \"off\"");
  features.velocity_input = f.opt<std::string>("velocity_input", features.velocity_input);
  require(features.velocity_input == "auto" || features.velocity_input == "on" ||
              features.velocity_input == "off",
          f.context("velocity_input"), "\"auto\", \"on\" or \"off\"");
}

// The features of training only: noise, pushforward, history, loss weights, augmentation.
void parse_training_features(JsonObjectReader& f, FeatureConfig& features) {
  features.density_noise_std = f.opt<double>("density_noise_std", features.density_noise_std);
  require(features.density_noise_std >= 0, f.context("density_noise_std"), ">= 0");
  features.pushforward = f.opt<int>("pushforward", features.pushforward);
  require(features.pushforward >= 0 && features.pushforward <= 100, f.context("pushforward"),
          "in 0..100 (frames rolled out before a sample; 0 = off)");
  features.pushforward_from = f.opt<int64_t>("pushforward_from", features.pushforward_from);
  require(features.pushforward_from >= 0, f.context("pushforward_from"), ">= 0 (a step)");
  features.pushforward_target =
      f.opt<std::string>("pushforward_target", features.pushforward_target);
  require(
      features.pushforward_target == "position" || features.pushforward_target == "acceleration",
      f.context("pushforward_target"), "\"position\" or \"acceleration\"");
  features.history = f.opt<int>("history", features.history);
  require(features.history >= 1 && features.history <= 10, f.context("history"),
          "in 1..10 (velocities the model sees: 1 = x_t - x_{t-1} only)");
  features.history_noise = f.opt<std::string>("history_noise", features.history_noise);
  require(features.history_noise == "off" || features.history_noise == "walk",
          f.context("history_noise"), "\"off\" or \"walk\"");
  features.rigid_loss_weight = f.opt<double>("rigid_loss_weight", features.rigid_loss_weight);
  require(features.rigid_loss_weight >= 0 && features.rigid_loss_weight <= 1000,
          f.context("rigid_loss_weight"), "in [0, 1000] (extra weight of the rigid part)");
  features.noise_rigid_scale = f.opt<double>("noise_rigid_scale", features.noise_rigid_scale);
  require(features.noise_rigid_scale >= 0 && features.noise_rigid_scale <= 1,
          f.context("noise_rigid_scale"), "in [0, 1] (share of the noise's rigid part kept)");
  features.augment = f.opt<std::string>("augment", features.augment);
  require(features.augment == "off" || features.augment == "symmetries", f.context("augment"),
          "\"off\" or \"symmetries\"");
}

void parse_features(const Json& j, const JsonContext& ctx, FeatureConfig& features) {
  JsonObjectReader f(j, ctx);
  features.contact_radius = auto_or_number<double>(
      f, "contact_radius", features.contact_radius, -1.0,
      [](double v) { return std::isfinite(v) && v >= 0; }, "\"auto\", 0 (off) or a radius > 0");
  features.noise_std = f.opt<double>("noise_std", features.noise_std);
  require(features.noise_std >= 0, f.context("noise_std"), ">= 0");
  features.noise_gamma = f.opt<double>("noise_gamma", features.noise_gamma);
  require(features.noise_gamma >= 0 && features.noise_gamma <= 1, f.context("noise_gamma"),
          "in [0, 1]");
  parse_feature_channels(f, features);
  parse_training_features(f, features);
  f.finish();
}

void parse_optimizer(const Json& j, const JsonContext& ctx, OptimizerConfig& optimizer) {
  JsonObjectReader o(j, ctx);
  optimizer.lr = o.opt<double>("lr", optimizer.lr);
  require(optimizer.lr > 0 && optimizer.lr < 1, o.context("lr"), "in (0, 1)");
  optimizer.lr_final = o.opt<double>("lr_final", optimizer.lr_final);
  require(optimizer.lr_final > 0 && optimizer.lr_final <= optimizer.lr, o.context("lr_final"),
          "in (0, lr]");
  optimizer.warmup_steps = o.opt<int64_t>("warmup_steps", optimizer.warmup_steps);
  require(optimizer.warmup_steps >= 0, o.context("warmup_steps"), ">= 0");
  optimizer.batch_size = o.opt<int>("batch_size", optimizer.batch_size);
  require(optimizer.batch_size >= 1 && optimizer.batch_size <= 1024, o.context("batch_size"),
          "in 1..1024");
  optimizer.ema_decay = o.opt<double>("ema_decay", optimizer.ema_decay);
  require(optimizer.ema_decay >= 0 && optimizer.ema_decay < 1, o.context("ema_decay"),
          "in [0, 1) (0: no average)");
  o.finish();
}

}  // namespace

TrainConfig parse_train_config(const Json& json, const std::string& file) {
  TrainConfig c;
  JsonObjectReader top(json, {file, ""});
  parse_run_keys(top, c);
  if (top.has("model")) parse_model(top.raw("model"), top.context("model"), c.model);
  if (top.has("features")) parse_features(top.raw("features"), top.context("features"), c.features);
  if (top.has("optimizer"))
    parse_optimizer(top.raw("optimizer"), top.context("optimizer"), c.optimizer);
  top.finish();
  return c;
}

double learning_rate(const OptimizerConfig& o, int64_t step, double progress) {
  const double decayed = o.lr * std::pow(o.lr_final / o.lr, std::clamp(progress, 0.0, 1.0));
  if (step >= o.warmup_steps) return decayed;
  const double ramp = static_cast<double>(step + 1) / static_cast<double>(o.warmup_steps);
  return decayed * (0.01 + 0.99 * ramp);
}

Json to_json(const TrainConfig& c) {
  Json contact = c.features.contact_radius < 0 ? Json("auto") : Json(c.features.contact_radius);
  Json levels = c.model.levels == 0 ? Json("auto") : Json(c.model.levels);
  Json j{{"data", c.data},
         {"steps", c.steps},
         {"time_budget_s", c.time_budget_s},
         {"valid_every", c.valid_every},
         {"valid_samples", c.valid_samples},
         {"valid_rollout_every", c.valid_rollout_every},
         {"valid_rollout_trajectories", c.valid_rollout_trajectories},
         {"normalizer_steps", c.normalizer_steps},
         {"seed", c.seed},
         {"graph_cache_mb", c.graph_cache_mb},
         {"model",
          {{"type", c.model.type},
           {"latent", c.model.latent},
           {"levels", levels},
           {"seeding", to_string(c.model.seeding)},
           {"message_passing_steps", c.model.message_passing_steps},
           {"mp_per_level", c.model.mp_per_level_list.empty() ? Json(c.model.mp_per_level)
                                                              : Json(c.model.mp_per_level_list)}}},
         {"features",
          {{"contact_radius", contact},
           {"noise_std", c.features.noise_std},
           {"noise_gamma", c.features.noise_gamma},
           {"strain", c.features.strain},
           {"num_node_types",
            c.features.num_node_types == 0 ? Json("auto") : Json(c.features.num_node_types)},
           {"walls", c.features.walls},
           {"momentum", c.features.momentum}}},
         {"optimizer",
          {{"lr", c.optimizer.lr},
           {"lr_final", c.optimizer.lr_final},
           {"warmup_steps", c.optimizer.warmup_steps},
           {"batch_size", c.optimizer.batch_size},
           {"ema_decay", c.optimizer.ema_decay}}}};
  j["model"]["precision"] = c.model.precision;
  j["model"]["edge_normalizer"] = c.model.edge_normalizer;
  Json& f = j["features"];
  f["output"] = c.features.output;
  f["kinematic_input"] = c.features.kinematic_input;
  f["stress"] = c.features.stress;
  f["output_statistics"] = c.features.output_statistics;
  f["velocity_input"] = c.features.velocity_input;
  f["density_noise_std"] = c.features.density_noise_std;
  f["pushforward"] = c.features.pushforward;
  f["pushforward_from"] = c.features.pushforward_from;
  f["pushforward_target"] = c.features.pushforward_target;
  f["history"] = c.features.history;
  f["history_noise"] = c.features.history_noise;
  f["rigid_loss_weight"] = c.features.rigid_loss_weight;
  f["noise_rigid_scale"] = c.features.noise_rigid_scale;
  f["augment"] = c.features.augment;
  return j;
}

}  // namespace bsms
