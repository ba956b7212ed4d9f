#include "data/mpm/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "core/runtime.hpp"
#include "core/xdmf_text.hpp"
#include "data/mpm/scene_builder.hpp"

namespace bsms::mpm {

std::string SimulationSummary::summary_line() const {
  std::ostringstream s;
  s.precision(4);
  s << steps << " steps, " << particles << " particles, " << frames << " frames in " << wall_s
    << " s (" << particle_steps_per_s / 1e6 << " M particle-steps/s); energy " << energy_initial
    << " -> " << energy_final << " J (drift " << energy_drift * 100.0 << " %), momentum drift "
    << momentum_drift;
  return s.str();
}

namespace {

template <int Dim>
void record(const MpmSolver<Dim>& solver, SimulationFrames& rec) {
  const Particles<Dim>& p = solver.particles();
  rec.time.push_back(solver.time());
  const size_t first = rec.position.size();
  for (int32_t i = 0; i < p.size(); ++i)
    for (int a = 0; a < Dim; ++a) {
      rec.position.push_back(static_cast<float>(p.x[i][a]));
      if (rec.has_velocity) rec.velocity.push_back(static_cast<float>(p.v[i][a]));
    }
  if (rec.has_stress)
    for (double s : solver.von_mises_stress()) rec.stress.push_back(static_cast<float>(s));
  if (rec.has_plastic_strain)
    for (double a : p.plastic_strain) rec.plastic_strain.push_back(static_cast<float>(a));
  const Diagnostics<Dim> d = solver.diagnostics();
  rec.energy.insert(rec.energy.end(), {d.kinetic, d.elastic, d.gravitational});
  for (int a = 0; a < Dim; ++a) rec.momentum.push_back(d.momentum[a]);
  for (int a = 0; a < Diagnostics<Dim>::kAngular; ++a) rec.angular_momentum.push_back(d.angular[a]);
  for (size_t k = first; k < rec.position.size(); ++k)
    if (!std::isfinite(rec.position[k]))
      throw NumericalError("non-finite position at t = " + std::to_string(solver.time()));
}

// DIR/frames.xdmf and the views it reads, DIR/frames.xdmf.h5. As for dataset XDMF
// (data/dataset/xdmf.hpp, where the readers' constraints are): each frame of a [T, P(, dim)]
// array of frames.h5 is a virtual dataset of the views file (no copy), positions and velocities
// with 3 components; the Polyvertex cells are an explicit index list, without which the Xdmf3
// readers make no cells.
void write_xdmf(const std::string& dir, const SimulationFrames& rec) {
  const std::string xdmf_path = (std::filesystem::path(dir) / "frames.xdmf").string();
  const std::string views = "frames.xdmf.h5";
  const int64_t frames = rec.num_frames(), particles = rec.particles;
  const hsize_t T = static_cast<hsize_t>(frames), P = static_cast<hsize_t>(particles);
  const hsize_t D = static_cast<hsize_t>(rec.dim);
  struct Field {
    const char* name;     // attribute name in the XDMF
    const char* dataset;  // in frames.h5
    bool vector;
  };
  std::vector<Field> fields;
  if (rec.has_velocity) fields.push_back({"velocity", "/frames/velocity", true});
  if (rec.has_stress) fields.push_back({"von_mises", "/frames/stress", false});
  if (rec.has_plastic_strain) fields.push_back({"plastic_strain", "/frames/plastic_strain", false});

  AtomicOutput views_out((std::filesystem::path(dir) / views).string());
  {
    H5File v(views_out.temp_path(), H5File::Mode::kTruncate);
    v.set_attr("/", "format", std::string("bsms-xdmf-views"));
    v.set_attr("/", "source", std::string("frames.h5"));
    std::vector<int32_t> index(static_cast<size_t>(particles));
    for (int64_t p = 0; p < particles; ++p) index[static_cast<size_t>(p)] = static_cast<int32_t>(p);
    v.write("/connectivity", index, {P});
    for (int64_t t = 0; t < frames; ++t) {
      v.write_virtual("/position/" + xdmf_index_name(t), "frames.h5", "/frames/position", {T, P, D},
                      t, 3);
      for (const auto& field : fields)
        v.write_virtual(std::string("/") + field.name + "/" + xdmf_index_name(t), "frames.h5",
                        field.dataset, field.vector ? Shape{T, P, D} : Shape{T, P}, t,
                        field.vector ? 3 : 0);
    }
    v.close();
  }

  AtomicOutput out(xdmf_path);
  {
    std::ofstream f(out.temp_path());
    const std::string p = std::to_string(particles);
    auto item = [](const std::string& dims, const char* type, int precision,
                   const std::string& file, const std::string& dataset) {
      return "          " + xdmf_hdf_item(dims, type, precision, file, dataset);
    };
    f << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
      << "    <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    f.precision(17);
    for (int64_t t = 0; t < frames; ++t) {
      f << "      <Grid Name=\"frame_" << t << "\" GridType=\"Uniform\">\n"
        << "        <Time Value=\"" << rec.time[t] << "\"/>\n"
        << "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << p
        << "\" NodesPerElement=\"1\">\n"
        << item(p, "Int", 4, views, "/connectivity") << "        </Topology>\n"
        << "        <Geometry GeometryType=\"XYZ\">\n"
        << item(p + " 3", "Float", 4, views, "/position/" + xdmf_index_name(t))
        << "        </Geometry>\n";
      for (const auto& field : fields)
        f << "        <Attribute Name=\"" << field.name << "\" AttributeType=\""
          << (field.vector ? "Vector" : "Scalar") << "\" Center=\"Node\">\n"
          << item(field.vector ? p + " 3" : p, "Float", 4, views,
                  std::string("/") + field.name + "/" + xdmf_index_name(t))
          << "        </Attribute>\n";
      f << "        <Attribute Name=\"mass\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        << item(p, "Float", 8, "frames.h5", "/particles/mass") << "        </Attribute>\n"
        << "      </Grid>\n";
    }
    f << "    </Grid>\n  </Domain>\n</Xdmf>\n";
    if (!f) throw IoError(out.temp_path() + ": write failed");
  }
  views_out.commit();
  out.commit();
}

template <int Dim>
SimulationSummary run(const Scene& scene, SimulationFrames& rec,
                      const SimulationProgress& progress) {
  BuiltScene<Dim> built = build_scene<Dim>(scene);
  rec = SimulationFrames();
  rec.dim = Dim;
  rec.mass = built.particles.mass;
  rec.volume0 = built.particles.volume0;
  rec.angular_width = Diagnostics<Dim>::kAngular;
  MpmSolver<Dim> solver(std::move(built.background), std::move(built.materials),
                        std::move(built.particles), std::move(built.constraints), built.settings);
  rec.particles = solver.particles().size();
  const auto& fields = scene.output.fields;
  rec.has_velocity = std::find(fields.begin(), fields.end(), "velocity") != fields.end();
  rec.has_stress = std::find(fields.begin(), fields.end(), "stress") != fields.end();
  rec.has_plastic_strain =
      std::find(fields.begin(), fields.end(), "plastic_strain") != fields.end();
  record(solver, rec);
  const Diagnostics<Dim> d0 = solver.diagnostics();
  double kinetic_max = d0.kinetic, speed_max = 0.0;  // Σ m |v|, the scale of momentum drift
  auto track_speed = [&] {
    double sum = 0.0;
    for (int32_t p = 0; p < solver.particles().size(); ++p)
      sum += rec.mass[p] * solver.particles().v[p].norm();
    speed_max = std::max(speed_max, sum);
  };
  track_speed();

  const int frames = scene.output.frames;
  Stopwatch clock;
  for (int k = 1; k < frames; ++k) {
    solver.advance_to(scene.solver.end_time * k / (frames - 1));
    record(solver, rec);
    kinetic_max = std::max(kinetic_max, solver.diagnostics().kinetic);
    track_speed();
    if (progress) progress(k, frames - 1, solver.steps());
  }
  SimulationSummary s;
  s.wall_s = clock.seconds();
  const Diagnostics<Dim> d1 = solver.diagnostics();
  s.steps = solver.steps();
  s.particles = solver.particles().size();
  s.frames = frames;
  s.particle_steps_per_s = static_cast<double>(s.steps) * s.particles / std::max(s.wall_s, 1e-9);
  s.energy_initial = d0.kinetic + d0.elastic + d0.gravitational;
  s.energy_final = d1.kinetic + d1.elastic + d1.gravitational;
  s.energy_drift = std::abs(s.energy_final - s.energy_initial) /
                   std::max({std::abs(s.energy_initial), kinetic_max, 1e-300});
  s.momentum_drift = (d1.momentum - d0.momentum).norm() / std::max(speed_max, 1e-300);
  return s;
}

}  // namespace

SimulationSummary solve_scene(const Scene& scene, SimulationFrames& frames,
                              const SimulationProgress& progress) {
  return scene.dim == 2 ? run<2>(scene, frames, progress) : run<3>(scene, frames, progress);
}

void write_simulation(const Scene& scene, const SimulationFrames& rec, const std::string& out_dir) {
  std::filesystem::create_directories(out_dir);
  const std::string h5_path = (std::filesystem::path(out_dir) / "frames.h5").string();
  AtomicOutput out(h5_path);
  {
    H5File f(out.temp_path(), H5File::Mode::kTruncate);
    const hsize_t T = rec.time.size(), P = static_cast<hsize_t>(rec.particles);
    const hsize_t D = static_cast<hsize_t>(rec.dim);
    f.set_attr("/", "format", std::string("bsms-frames"));
    f.set_attr("/", "version", static_cast<int64_t>(1));
    f.set_attr("/", "scene", scene.source.dump());
    f.set_attr("/", "dim", static_cast<int64_t>(rec.dim));
    f.set_attr("/", "kernel", to_string(scene.solver.kernel));
    f.set_attr("/", "transfer", to_string(scene.solver.transfer));
    f.write<double>("/particles/mass", rec.mass, {P});
    f.write<double>("/particles/volume0", rec.volume0, {P});
    f.write<double>("/frames/time", rec.time, {T});
    f.write<float>("/frames/position", rec.position, {T, P, D}, 1);
    if (rec.has_velocity) f.write<float>("/frames/velocity", rec.velocity, {T, P, D}, 1);
    if (rec.has_stress) f.write<float>("/frames/stress", rec.stress, {T, P}, 1);
    if (rec.has_plastic_strain)
      f.write<float>("/frames/plastic_strain", rec.plastic_strain, {T, P}, 1);
    f.write<double>("/frames/energy", rec.energy, {T, 3});
    f.write<double>("/frames/momentum", rec.momentum, {T, D});
    f.write<double>("/frames/angular_momentum", rec.angular_momentum,
                    {T, static_cast<hsize_t>(rec.angular_width)});
    f.close();
  }
  out.commit();
  write_xdmf(out_dir, rec);
  AtomicOutput resolved((std::filesystem::path(out_dir) / "scene.json").string());
  {
    std::ofstream f(resolved.temp_path());
    f << scene.source.dump(2) << "\n";
    if (!f) throw IoError(resolved.temp_path() + ": write failed");
  }
  resolved.commit();
}

SimulationSummary simulate_scene(const Scene& scene, const std::string& out_dir, bool progress) {
  std::unique_ptr<ProgressBar> bar;
  if (progress) bar = std::make_unique<ProgressBar>("simulate", scene.output.frames - 1);
  SimulationFrames frames;
  const SimulationSummary s = solve_scene(scene, frames, [&](int64_t done, int64_t, int64_t steps) {
    if (bar) bar->update(done, std::to_string(steps) + " steps");
  });
  if (bar) bar->finish();
  write_simulation(scene, frames, out_dir);
  return s;
}

}  // namespace bsms::mpm
