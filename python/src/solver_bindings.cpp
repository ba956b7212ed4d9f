// bsms.simulate and bsms.generate: the UMLS-MPM solver and the trajectory generator.
#include <filesystem>
#include <string>
#include <vector>

#include "common.hpp"
#include "core/config.hpp"
#include "core/runtime.hpp"
#include "data/generate/generator.hpp"
#include "data/mpm/scene_config.hpp"
#include "data/mpm/scene_size.hpp"
#include "data/mpm/simulation.hpp"

namespace bsms::python {
namespace {

// A config given as a path (`text` empty) or as a dict dumped to JSON text by bsms/__init__.py,
// with `--set` overrides applied either way. `what` names a dict in messages.
Json config_json(const std::string& path, const std::string& text,
                 const std::vector<std::string>& sets, const std::string& what) {
  Json json = text.empty() ? load_json_file(path) : parse_json_text(text, what);
  for (const std::string& s : sets) apply_override(json, s, text.empty() ? path : what);
  return json;
}

// The progress callback of a long call, run with the GIL held; `callback` lives in the binding's
// frame, so no Python object is copied or freed without the GIL.
template <class... Args>
std::function<void(Args...)> with_gil(const py::object& callback) {
  if (callback.is_none()) return {};
  return [&callback](Args... args) {
    py::gil_scoped_acquire gil;
    callback(args...);
  };
}

void make_output_dir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    throw InputError(dir + ": cannot create the output folder (" +
                     (ec ? ec.message() : std::string("not a folder")) + ")");
}

py::dict frames_dict(mpm::SimulationFrames&& f) {
  const py::ssize_t t = f.num_frames(), p = f.particles, dim = f.dim;
  py::dict d;
  d["time"] = to_numpy(std::move(f.time), {t});
  d["position"] = to_numpy(std::move(f.position), {t, p, dim});
  if (f.has_velocity) d["velocity"] = to_numpy(std::move(f.velocity), {t, p, dim});
  if (f.has_stress) d["stress"] = to_numpy(std::move(f.stress), {t, p});
  if (f.has_plastic_strain) d["plastic_strain"] = to_numpy(std::move(f.plastic_strain), {t, p});
  d["energy"] = to_numpy(std::move(f.energy), {t, 3});
  d["momentum"] = to_numpy(std::move(f.momentum), {t, dim});
  d["angular_momentum"] = to_numpy(std::move(f.angular_momentum), {t, f.angular_width});
  d["mass"] = to_numpy(std::move(f.mass), {p});
  d["volume0"] = to_numpy(std::move(f.volume0), {p});
  return d;
}

}  // namespace

void bind_solver(py::module_& m) {
  m.def(
      "_simulate",
      [](const std::string& path, const std::string& text, const std::vector<std::string>& sets,
         int threads, const std::string& out, const py::object& progress) {
        const mpm::Scene scene = mpm::parse_scene(config_json(path, text, sets, "scene (dict)"),
                                                  text.empty() ? path : "scene (dict)");
        mpm::check_scene_size(scene);
        mpm::SimulationFrames frames;
        mpm::SimulationSummary s;
        const auto told = with_gil<int64_t, int64_t>(progress);
        run_unlocked([&] {
          if (!out.empty()) make_output_dir(out);
          const ThreadScope scope(threads);
          s = mpm::solve_scene(scene, frames, [&](int64_t done, int64_t total, int64_t) {
            if (told) told(done, total);
          });
          if (!out.empty()) mpm::write_simulation(scene, frames, out);
        });
        py::dict d = frames_dict(std::move(frames));
        d["summary"] = py::dict(py::arg("steps") = s.steps, py::arg("particles") = s.particles,
                                py::arg("frames") = s.frames, py::arg("wall_s") = s.wall_s,
                                py::arg("energy_drift") = s.energy_drift,
                                py::arg("momentum_drift") = s.momentum_drift,
                                py::arg("line") = s.summary_line());
        d["scene"] = scene.source.dump();
        return d;
      },
      py::arg("path"), py::arg("text"), py::arg("sets"), py::arg("threads"), py::arg("out"),
      py::arg("progress"));

  m.def(
      "_generate",
      [](const std::string& path, const std::string& text, const std::string& out,
         int64_t trajectories, const std::string& split, int64_t seed, int threads,
         const std::string& shard, const std::vector<std::string>& sets,
         const py::object& progress) {
        if (trajectories < 1) throw InputError("generate: trajectories must be at least 1");
        generate::GenerateOptions options;
        options.out_dir = out;
        options.trajectories = trajectories;
        options.split = generate::parse_split(split, "split");
        options.shard = generate::parse_shard(shard, "shard");
        options.seed = seed;
        options.on_progress = with_gil<int64_t, int64_t>(progress);
        const generate::FamilyConfig family = generate::parse_family(
            config_json(path, text, sets, "family (dict)"), text.empty() ? path : "family (dict)");
        const generate::GenerateSummary s = run_unlocked([&] {
          const ThreadScope scope(threads);
          options.threads = scope.threads();
          return generate::generate_dataset(family, options);
        });
        return py::dict(py::arg("generated") = s.generated, py::arg("resumed") = s.resumed,
                        py::arg("redraws") = s.redraws, py::arg("wall_s") = s.wall_s,
                        py::arg("solver_s") = s.solver_s, py::arg("merged") = s.merged,
                        py::arg("train") = s.counts.train, py::arg("valid") = s.counts.valid,
                        py::arg("test") = s.counts.test, py::arg("line") = s.summary_line());
      },
      py::arg("path"), py::arg("text"), py::arg("out"), py::arg("trajectories"), py::arg("split"),
      py::arg("seed"), py::arg("threads"), py::arg("shard"), py::arg("sets"), py::arg("progress"));
}

}  // namespace bsms::python
