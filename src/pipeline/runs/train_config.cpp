#include "pipeline/runs/train_config.hpp"

#include <algorithm>
#include <cmath>

namespace bsms {

TrainConfig parse_train_config(const Json& json, const std::string& file) {
  TrainConfig c;
  JsonObjectReader top(json, {file, ""});
  c.data = top.get<std::string>("data");
  c.steps = top.get<int64_t>("steps");
  require(c.steps >= 1, top.context("steps"), "a positive integer");
  c.time_budget_s = top.opt<double>("time_budget_s", c.time_budget_s);
  require(c.time_budget_s >= 0, top.context("time_budget_s"), ">= 0 (0 = no budget)");
  c.valid_every = top.opt<int64_t>("valid_every", c.valid_every);
  require(c.valid_every >= 1, top.context("valid_every"), "a positive integer");
  c.valid_samples = top.opt<int>("valid_samples", c.valid_samples);
  require(c.valid_samples >= 1, top.context("valid_samples"), "a positive integer");
  c.normalizer_steps = top.opt<int64_t>("normalizer_steps", c.normalizer_steps);
  require(c.normalizer_steps >= 1, top.context("normalizer_steps"), "a positive integer");
  c.seed = top.opt<uint64_t>("seed", c.seed);
  c.graph_cache_mb = top.opt<int64_t>("graph_cache_mb", c.graph_cache_mb);
  require(c.graph_cache_mb >= 0, top.context("graph_cache_mb"), ">= 0 (0 = no cap)");

  if (top.has("model")) {
    JsonObjectReader m(top.raw("model"), top.context("model"));
    c.model.type = m.opt<std::string>("type", c.model.type);
    require(c.model.type == "bsms" || c.model.type == "mgn", m.context("type"),
            "\"bsms\" or \"mgn\"");
    c.model.latent = m.opt<int64_t>("latent", c.model.latent);
    require(c.model.latent >= 1 && c.model.latent <= 4096, m.context("latent"), "in 1..4096");
    if (m.has("levels") && m.raw("levels").is_string()) {
      require(m.raw("levels").get<std::string>() == "auto", m.context("levels"),
              "\"auto\" or an integer >= 1");
      c.model.levels = 0;
    } else {
      c.model.levels = m.opt<int>("levels", 0);
      require(c.model.levels >= 0 && c.model.levels <= 64, m.context("levels"),
              "\"auto\" or an integer in 1..64");
    }
    const std::string seeding = m.opt<std::string>("seeding", to_string(c.model.seeding));
    try {
      c.model.seeding = parse_seeding(seeding);
    } catch (const InputError&) {
      require(false, m.context("seeding"), "one of minave, closecenter, random");
    }
    c.model.message_passing_steps =
        m.opt<int>("message_passing_steps", c.model.message_passing_steps);
    require(c.model.message_passing_steps >= 1 && c.model.message_passing_steps <= 100,
            m.context("message_passing_steps"), "in 1..100");
    if (m.has("mp_per_level") && m.raw("mp_per_level").is_array()) {
      const Json& list = m.raw("mp_per_level");
      bool ok = !list.empty() && list.size() <= 64;
      for (const auto& v : list) {
        ok = ok && v.is_number_integer() && v.get<int64_t>() >= 1 && v.get<int64_t>() <= 16;
        if (ok) c.model.level_blocks.push_back(v.get<int>());
      }
      require(ok, m.context("mp_per_level"),
              "an integer in 1..16 or a list of them, one per level from the mesh down");
      if (c.model.levels > 0)
        require(static_cast<int>(list.size()) == c.model.levels, m.context("mp_per_level"),
                "one block count per level (" + std::to_string(c.model.levels) + " levels)");
      c.model.mp_per_level =
          *std::max_element(c.model.level_blocks.begin(), c.model.level_blocks.end());
    } else {
      c.model.mp_per_level = m.opt<int>("mp_per_level", c.model.mp_per_level);
      require(c.model.mp_per_level >= 1 && c.model.mp_per_level <= 16, m.context("mp_per_level"),
              "in 1..16");
    }
    c.model.precision = m.opt<std::string>("precision", c.model.precision);
    require(c.model.precision == "float32" || c.model.precision == "bf16", m.context("precision"),
            "\"float32\" or \"bf16\"");
    c.model.edge_normalizer = m.opt<std::string>("edge_normalizer", c.model.edge_normalizer);
    require(c.model.edge_normalizer == "on" || c.model.edge_normalizer == "off",
            m.context("edge_normalizer"), "\"on\" or \"off\"");
    m.finish();
  }
  if (top.has("features")) {
    JsonObjectReader f(top.raw("features"), top.context("features"));
    if (f.has("contact_radius") && f.raw("contact_radius").is_string()) {
      require(f.raw("contact_radius").get<std::string>() == "auto", f.context("contact_radius"),
              "\"auto\", 0 (off) or a radius > 0");
      c.features.contact_radius = -1.0;
    } else {
      c.features.contact_radius = f.opt<double>("contact_radius", c.features.contact_radius);
    }
    c.features.noise_std = f.opt<double>("noise_std", c.features.noise_std);
    require(c.features.noise_std >= 0, f.context("noise_std"), ">= 0");
    c.features.noise_gamma = f.opt<double>("noise_gamma", c.features.noise_gamma);
    require(c.features.noise_gamma >= 0 && c.features.noise_gamma <= 1, f.context("noise_gamma"),
            "in [0, 1]");
    c.features.strain = f.opt<std::string>("strain", c.features.strain);
    require(c.features.strain == "auto" || c.features.strain == "off", f.context("strain"),
            "\"auto\" or \"off\"");
    c.features.num_node_types = f.opt<int>("num_node_types", c.features.num_node_types);
    require(c.features.num_node_types >= 0 && c.features.num_node_types <= 64,
            f.context("num_node_types"), "in 0..64 (0 = auto)");
    c.features.walls = f.opt<std::string>("walls", c.features.walls);
    require(c.features.walls == "auto" || c.features.walls == "off", f.context("walls"),
            "\"auto\" or \"off\"");
    c.features.momentum = f.opt<std::string>("momentum", c.features.momentum);
    require(c.features.momentum == "auto" || c.features.momentum == "free" ||
                c.features.momentum == "off",
            f.context("momentum"), "\"auto\", \"free\" or \"off\"");
    c.features.output = f.opt<std::string>("output", c.features.output);
    require(c.features.output == "auto" || c.features.output == "acceleration" ||
                c.features.output == "velocity",
            f.context("output"), "\"auto\", \"acceleration\" or \"velocity\"");
    c.features.stress = f.opt<std::string>("stress", c.features.stress);
    require(c.features.stress == "auto" || c.features.stress == "off", f.context("stress"),
            "\"auto\" or \"off\"");
    c.features.output_statistics =
        f.opt<std::string>("output_statistics", c.features.output_statistics);
    require(c.features.output_statistics == "auto" || c.features.output_statistics == "all" ||
                c.features.output_statistics == "predicted",
            f.context("output_statistics"), "\"auto\", \"all\" or \"predicted\"");
    c.features.kinematic_input = f.opt<std::string>("kinematic_input", c.features.kinematic_input);
    require(c.features.kinematic_input == "auto" || c.features.kinematic_input == "on" ||
                c.features.kinematic_input == "off",
            f.context("kinematic_input"), "\"auto\", \"on\" or \"off\"");
    c.features.velocity_input = f.opt<std::string>("velocity_input", c.features.velocity_input);
    require(c.features.velocity_input == "auto" || c.features.velocity_input == "on" ||
                c.features.velocity_input == "off",
            f.context("velocity_input"), "\"auto\", \"on\" or \"off\"");
    c.features.density_noise_std = f.opt<double>("density_noise_std", c.features.density_noise_std);
    require(c.features.density_noise_std >= 0, f.context("density_noise_std"), ">= 0");
    c.features.pushforward = f.opt<int>("pushforward", c.features.pushforward);
    require(c.features.pushforward >= 0 && c.features.pushforward <= 100, f.context("pushforward"),
            "in 0..100 (frames rolled out before a sample; 0 = off)");
    c.features.pushforward_from = f.opt<int64_t>("pushforward_from", c.features.pushforward_from);
    require(c.features.pushforward_from >= 0, f.context("pushforward_from"), ">= 0 (a step)");
    c.features.pushforward_target =
        f.opt<std::string>("pushforward_target", c.features.pushforward_target);
    require(c.features.pushforward_target == "position" ||
                c.features.pushforward_target == "acceleration",
            f.context("pushforward_target"), "\"position\" or \"acceleration\"");
    c.features.history = f.opt<int>("history", c.features.history);
    require(c.features.history >= 1 && c.features.history <= 10, f.context("history"),
            "in 1..10 (velocities the model sees: 1 = x_t - x_{t-1} only)");
    c.features.history_noise = f.opt<std::string>("history_noise", c.features.history_noise);
    require(c.features.history_noise == "off" || c.features.history_noise == "walk",
            f.context("history_noise"), "\"off\" or \"walk\"");
    c.features.rigid_loss_weight = f.opt<double>("rigid_loss_weight", c.features.rigid_loss_weight);
    require(c.features.rigid_loss_weight >= 0 && c.features.rigid_loss_weight <= 1000,
            f.context("rigid_loss_weight"), "in [0, 1000] (extra weight of the rigid part)");
    c.features.noise_rigid_scale = f.opt<double>("noise_rigid_scale", c.features.noise_rigid_scale);
    require(c.features.noise_rigid_scale >= 0 && c.features.noise_rigid_scale <= 1,
            f.context("noise_rigid_scale"), "in [0, 1] (share of the noise's rigid part kept)");
    c.features.augment = f.opt<std::string>("augment", c.features.augment);
    require(c.features.augment == "off" || c.features.augment == "symmetries", f.context("augment"),
            "\"off\" or \"symmetries\"");
    f.finish();
  }
  if (top.has("optimizer")) {
    JsonObjectReader o(top.raw("optimizer"), top.context("optimizer"));
    c.optimizer.lr = o.opt<double>("lr", c.optimizer.lr);
    require(c.optimizer.lr > 0 && c.optimizer.lr < 1, o.context("lr"), "in (0, 1)");
    c.optimizer.lr_final = o.opt<double>("lr_final", c.optimizer.lr_final);
    require(c.optimizer.lr_final > 0 && c.optimizer.lr_final <= c.optimizer.lr,
            o.context("lr_final"), "in (0, lr]");
    c.optimizer.warmup_steps = o.opt<int64_t>("warmup_steps", c.optimizer.warmup_steps);
    require(c.optimizer.warmup_steps >= 0, o.context("warmup_steps"), ">= 0");
    c.optimizer.batch_size = o.opt<int>("batch_size", c.optimizer.batch_size);
    require(c.optimizer.batch_size >= 1 && c.optimizer.batch_size <= 1024, o.context("batch_size"),
            "in 1..1024");
    o.finish();
  }
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
         {"normalizer_steps", c.normalizer_steps},
         {"seed", c.seed},
         {"graph_cache_mb", c.graph_cache_mb},
         {"model",
          {{"type", c.model.type},
           {"latent", c.model.latent},
           {"levels", levels},
           {"seeding", to_string(c.model.seeding)},
           {"message_passing_steps", c.model.message_passing_steps},
           {"mp_per_level", c.model.level_blocks.empty() ? Json(c.model.mp_per_level)
                                                         : Json(c.model.level_blocks)}}},
         {"features",
          {{"contact_radius", contact},
           {"noise_std", c.features.noise_std},
           {"noise_gamma", c.features.noise_gamma},
           {"strain", c.features.strain},
           {"num_node_types", c.features.num_node_types},
           {"walls", c.features.walls},
           {"momentum", c.features.momentum}}},
         {"optimizer",
          {{"lr", c.optimizer.lr},
           {"lr_final", c.optimizer.lr_final},
           {"warmup_steps", c.optimizer.warmup_steps},
           {"batch_size", c.optimizer.batch_size}}}};
  // Keys added later are written only when set, so that runs trained before them still match
  // their saved configuration on --resume.
  if (c.model.precision != ModelConfig().precision) j["model"]["precision"] = c.model.precision;
  if (c.model.edge_normalizer != ModelConfig().edge_normalizer)
    j["model"]["edge_normalizer"] = c.model.edge_normalizer;
  const FeatureConfig defaults;
  Json& f = j["features"];
  if (c.features.output != defaults.output) f["output"] = c.features.output;
  if (c.features.kinematic_input != defaults.kinematic_input)
    f["kinematic_input"] = c.features.kinematic_input;
  if (c.features.stress != defaults.stress) f["stress"] = c.features.stress;
  if (c.features.output_statistics != defaults.output_statistics)
    f["output_statistics"] = c.features.output_statistics;
  if (c.features.velocity_input != defaults.velocity_input)
    f["velocity_input"] = c.features.velocity_input;
  if (c.features.density_noise_std != defaults.density_noise_std)
    f["density_noise_std"] = c.features.density_noise_std;
  if (c.features.pushforward != defaults.pushforward) {
    f["pushforward"] = c.features.pushforward;
    f["pushforward_from"] = c.features.pushforward_from;
    f["pushforward_target"] = c.features.pushforward_target;
  }
  if (c.features.history != defaults.history) f["history"] = c.features.history;
  if (c.features.history_noise != defaults.history_noise)
    f["history_noise"] = c.features.history_noise;
  if (c.features.rigid_loss_weight != defaults.rigid_loss_weight)
    f["rigid_loss_weight"] = c.features.rigid_loss_weight;
  if (c.features.noise_rigid_scale != defaults.noise_rigid_scale)
    f["noise_rigid_scale"] = c.features.noise_rigid_scale;
  if (c.features.augment != defaults.augment) f["augment"] = c.features.augment;
  return j;
}

}  // namespace bsms
