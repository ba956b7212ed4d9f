#include "data/mpm/solver.hpp"

#include <omp.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <sstream>

#include "core/error.hpp"

namespace bsms::mpm {

std::string to_string(Transfer transfer) {
  return transfer == Transfer::kApic ? "apic" : "flip";
}

Transfer parse_transfer(const std::string& name, const std::string& where) {
  if (name == "apic") return Transfer::kApic;
  if (name == "flip") return Transfer::kFlip;
  throw InputError(where + ": unknown transfer '" + name + "' (allowed: apic, flip)");
}

std::string to_string(BoundaryType type) {
  switch (type) {
    case BoundaryType::kFixed:
      return "fixed";
    case BoundaryType::kRoller:
      return "roller";
    case BoundaryType::kSlip:
      return "slip";
  }
  return "unknown";
}

BoundaryType parse_boundary_type(const std::string& name, const std::string& where) {
  for (BoundaryType t : {BoundaryType::kFixed, BoundaryType::kRoller, BoundaryType::kSlip})
    if (to_string(t) == name) return t;
  throw InputError(where + ": unknown boundary type '" + name + "' (allowed: fixed, roller, slip)");
}

template <int Dim>
void Particles<Dim>::resize(int32_t n) {
  x.resize(n, Vec<Dim>::Zero());
  v.resize(n, Vec<Dim>::Zero());
  F.resize(n, Mat<Dim>::Identity());
  B.resize(n, Mat<Dim>::Zero());
  mass.resize(n, 0.0);
  volume0.resize(n, 0.0);
  material.resize(n, 0);
  body.resize(n, 0);
  plastic_strain.resize(n, 0.0);
}

namespace {

// Signed-mass share ρ = m_i / Σ_p |w_ip| m_p below which a node starts paying its momentum back
// by |w| instead of w: λ = clamp(1 − ρ / κ, 0, 1).
// MLS weights can be negative at the far edge of a particle's support, so the signed mass
// m_i = Σ w m_p of a node can be tiny, zero or negative while its momentum and force are
// not. Dropping such a node loses them (measured: the rotating square's momenta jumped
// from 1e-16 to 1e-7 / 1e-6 at the first such node, step 13943), and dividing by a
// cancelled mass blows its velocity up. Instead the node pays its momentum q_i = p_i + dt
// f_i back with the weights w' = w + λ (|w| − w), i.e. v_i = q_i / Σ w' m_p: with λ = 0
// this is APIC itself, with λ = 1 particle p gets the share |w| m_p / Σ|w| m (APIC again
// when all weights share a sign). Any λ conserves linear and angular momentum, APIC terms
// included; λ grows continuously as ρ = m_i / Σ|w| m falls below κ, so no rounding
// difference flips a discrete choice.
constexpr double kSharedMassFraction = 0.05;

// First failure found by any thread: the lowest particle index wins (deterministic message).
struct Failure {
  int32_t particle = INT_MAX;
  std::string cause;
  void record(int32_t p, std::string why) {
#pragma omp critical(bsms_mpm_failure)
    if (p < particle) {
      particle = p;
      cause = std::move(why);
    }
  }
  bool failed() const {
    return particle != INT_MAX;
  }
};

template <int Dim>
std::string format_vec(const Vec<Dim>& x) {
  std::ostringstream s;
  s.precision(6);
  s << "(";
  for (int a = 0; a < Dim; ++a) s << (a ? ", " : "") << x[a];
  s << ")";
  return s.str();
}

template <int Dim>
bool all_finite(const Vec<Dim>& x) {
  return x.allFinite();
}

// Why a particle's kernel evaluation failed (n < 0, as returned by TransferKernel), at position xp.
template <int Dim>
std::string kernel_failure(int n, const Vec<Dim>& xp) {
  return n == kOutsideMesh
             ? "left the background mesh at " + format_vec<Dim>(xp)
             : "degenerate kernel samples (singular MLS moment matrix) at " + format_vec<Dim>(xp);
}

// Mirror image of velocity v for a ghost node of wall con (see NodeConstraint).
template <int Dim>
Vec<Dim> reflect_at_wall(const NodeConstraint<Dim>& con, const Vec<Dim>& v) {
  const double nn = con.normal.squaredNorm();
  if (con.type == BoundaryType::kFixed || nn == 0.0) return -v;
  const double vdot = v.dot(con.normal);
  if (con.type == BoundaryType::kSlip && vdot <= 0.0) return v;
  return v - 2.0 * vdot / nn * con.normal;
}

}  // namespace

template <int Dim>
MpmSolver<Dim>::MpmSolver(BackgroundMesh<Dim> background, std::vector<Material> materials,
                          Particles<Dim> particles, std::vector<NodeConstraint<Dim>> constraints,
                          SolverSettings<Dim> settings)
    : bg_(std::move(background)),
      kernel_(settings.kernel, bg_),
      materials_(std::move(materials)),
      particles_(std::move(particles)),
      settings_(settings) {
  const int32_t n = bg_.num_nodes();
  constraint_offsets_.assign(n + 1, 0);
  for (const auto& c : constraints) {
    if (c.node < 0 || c.node >= n)
      throw InputError("boundary constraint on a node outside the background");
    // Ghosts are first constrained like wall nodes, so a mirror that reads a ghost sees a
    // constrained value, then overwritten by their mirror image.
    if (c.mirror_count > 0) ghosts_.push_back(c);
    ++constraint_offsets_[c.node + 1];
  }
  ghost_writes_.assign(ghosts_.size(), 1);
  {
    std::vector<uint8_t> seen(n, 0);
    for (size_t g = ghosts_.size(); g-- > 0;) {
      if (seen[ghosts_[g].node]) ghost_writes_[g] = 0;
      seen[ghosts_[g].node] = 1;
    }
  }
  for (int32_t i = 0; i < n; ++i) constraint_offsets_[i + 1] += constraint_offsets_[i];
  constraints_.resize(constraint_offsets_[n]);
  std::vector<int32_t> fill(constraint_offsets_.begin(), constraint_offsets_.end() - 1);
  for (const auto& c : constraints) constraints_[fill[c.node]++] = c;
  for (const auto& m : materials_) {
    max_wave_speed_ = std::max(max_wave_speed_, m.wave_speed());
    max_kinematic_viscosity_ = std::max(max_kinematic_viscosity_, m.viscosity / m.density);
  }

  const int32_t P = particles_.size();
  if (particles_.plastic_strain.empty()) particles_.plastic_strain.assign(P, 0.0);
  if (static_cast<int32_t>(particles_.plastic_strain.size()) != P)
    throw InputError("particle arrays differ in size (plastic_strain)");
  cell_.assign(P, -1);
  bary_.assign(P, Eigen::Matrix<double, Dim + 1, 1>::Zero());
  sigma_.assign(P, Mat<Dim>::Zero());
  psi_.assign(P, 0.0);
  entry_offsets_.assign(P + 1, 0);
  entry_counts_.assign(P, 0);
  grid_mass_.assign(n, 0.0);
  grid_v_.assign(n, Vec<Dim>::Zero());
  grid_v_new_.assign(n, Vec<Dim>::Zero());
  grid_share_.assign(n, 0.0);
  affine_.assign(P, Mat<Dim>::Zero());
  ghost_v_.assign(ghosts_.size(), Vec<Dim>::Zero());
  ghost_v_new_.assign(ghosts_.size(), Vec<Dim>::Zero());
  for (int32_t p = 0; p < P; ++p) {
    if (particles_.material[p] < 0 ||
        particles_.material[p] >= static_cast<int32_t>(materials_.size()))
      throw InputError("particle " + std::to_string(p) + " has no material");
    if (particles_.F[p].determinant() <= 0.0) fail(p, "initial deformation gradient has J <= 0");
    update_stress(p);
    Eigen::Matrix<double, Dim + 1, 1> bary;
    if (!bg_.grid) cell_[p] = bg_.locate(particles_.x[p], -1, bary);
  }
}

template <int Dim>
void MpmSolver<Dim>::fail(int32_t particle, const std::string& cause) const {
  throw NumericalError("step " + std::to_string(steps_ + 1) + " (t = " + std::to_string(time_) +
                       " s), particle " + std::to_string(particle) + ": " + cause);
}

template <int Dim>
void MpmSolver<Dim>::update_stress(int32_t p) {
  const Material& m = materials_[particles_.material[p]];
  elastic_response<Dim>(m, particles_.F[p], sigma_[p], psi_[p]);
}

template <int Dim>
std::vector<double> MpmSolver<Dim>::von_mises_stress() const {
  std::vector<double> out(particles_.size());
  for (int32_t p = 0; p < particles_.size(); ++p) out[p] = von_mises<Dim>(sigma_[p]);
  return out;
}

template <int Dim>
double MpmSolver<Dim>::stable_dt() const {
  if (settings_.fixed_dt > 0.0) return settings_.fixed_dt;
  double vmax = 0.0;
  const int32_t P = particles_.size();
#pragma omp parallel for reduction(max : vmax) schedule(static)
  for (int32_t p = 0; p < P; ++p) vmax = std::max(vmax, particles_.v[p].norm());
  const double h = kernel_.cfl_spacing();
  const double dt = settings_.cfl * h / (max_wave_speed_ + vmax);
  // Explicit viscosity is a diffusion of velocity, stable alone for dt ≤ h² / (2 Dim ν). Damping
  // also lowers the elastic limit of explicit stepping (2/ω (sqrt(1 + ζ²) − ζ) for a mode of
  // damping ratio ζ): the two limits are combined harmonically, which stays below both.
  if (max_kinematic_viscosity_ <= 0.0) return dt;
  const double viscous = settings_.cfl * h * h / (2.0 * Dim * max_kinematic_viscosity_);
  return 1.0 / (1.0 / dt + 1.0 / viscous);
}

template <int Dim>
void MpmSolver<Dim>::advance_to(double t) {
  while (time_ < t) {
    double dt = stable_dt();
    const double remaining = t - time_;
    // Summed fixed steps drift from the frame times by up to ~1e-8 dt after thousands of steps:
    // a step within 1e-6 of the remaining time takes all of it (a 1e-9 margin split every
    // frame after t = 0.5 s into two half steps: 100,050 steps instead of 100,000), and a
    // sliver left over is no step at all.
    if (remaining <= 1e-9 * dt) {
      time_ = t;
      break;
    }
    if (dt >= remaining * (1.0 - 1e-6)) {
      dt = remaining;
    } else if (dt > 0.5 * remaining) {
      dt = 0.5 * remaining;  // two even steps instead of one full and one sliver
    }
    step(dt);
    if (dt == remaining) time_ = t;
  }
}

template <int Dim>
void MpmSolver<Dim>::step(double dt) {
  locate_particles();
  particles_to_grid(dt);
  grid_to_particles(dt);
  time_ += dt;
  ++steps_;
}

template <int Dim>
void MpmSolver<Dim>::locate_particles() {
  const int32_t P = particles_.size();
  Failure failure;
  const bool simplicial = !bg_.grid;
  const bool per_cell =
      kernel_.type() == KernelType::kUmls || kernel_.type() == KernelType::kUmlsNoEta;
#pragma omp parallel for schedule(static)
  for (int32_t p = 0; p < P; ++p) {
    int64_t bound = kernel_.max_entries();
    if (simplicial) {
      const int32_t c = bg_.locate(particles_.x[p], cell_[p], bary_[p]);
      if (c < 0) {
        failure.record(p, "left the background mesh at " + format_vec<Dim>(particles_.x[p]));
        bound = 0;
      } else {
        cell_[p] = c;
        if (per_cell) bound = bg_.stencil_offsets[c + 1] - bg_.stencil_offsets[c];
      }
    }
    entry_offsets_[p + 1] = bound;
  }
  if (failure.failed()) fail(failure.particle, failure.cause);
  for (int32_t p = 0; p < P; ++p) entry_offsets_[p + 1] += entry_offsets_[p];
  if (static_cast<int64_t>(entries_.size()) < entry_offsets_[P]) entries_.resize(entry_offsets_[P]);
}

template <int Dim>
Mat<Dim> MpmSolver<Dim>::apic_affine(int32_t p, const KernelEntry<Dim>* e, int n) const {
  const Vec<Dim>& xp = particles_.x[p];
  Mat<Dim> D = Mat<Dim>::Zero();
  for (int i = 0; i < n; ++i) {
    const Vec<Dim> r = bg_.points[e[i].node] - xp;
    D.noalias() += e[i].w * r * r.transpose();
  }
  // D is invertible for UMLS and B-splines; linear FEM makes it singular on cell edges, where the
  // affine term is dropped.
  Mat<Dim> D_inv;
  bool invertible;
  D.computeInverseWithCheck(D_inv, invertible, 1e-14 * D.trace() * D.trace());
  if (invertible) return particles_.B[p] * D_inv;
  return Mat<Dim>::Zero();
}

template <int Dim>
void MpmSolver<Dim>::constrain_node(int32_t i, Vec<Dim>& vn) const {
  for (int32_t c = constraint_offsets_[i]; c < constraint_offsets_[i + 1]; ++c) {
    const NodeConstraint<Dim>& con = constraints_[c];
    const double nn = con.normal.squaredNorm();
    if (con.type == BoundaryType::kFixed || nn == 0.0) {
      vn.setZero();
    } else {
      const double vdot = vn.dot(con.normal);
      if (con.type == BoundaryType::kRoller || vdot > 0.0) vn -= vdot / nn * con.normal;
    }
  }
}

template <int Dim>
bool MpmSolver<Dim>::update_node(int32_t i, const double* acc, double dt) {
  grid_mass_[i] = acc[0];
  if (!(acc[1] > 0.0)) {  // no particle reaches the node
    grid_v_[i].setZero();
    grid_v_new_[i].setZero();
    grid_share_[i] = 0.0;
    return false;
  }
  // A node whose signed mass is cancelled pays its momentum back by w + λ (|w| − w) (see
  // kSharedMassFraction).
  const double lambda = std::clamp(1.0 - acc[0] / (kSharedMassFraction * acc[1]), 0.0, 1.0);
  grid_share_[i] = lambda;
  Vec<Dim> v, f;
  const double m_eff = acc[0] + lambda * (acc[1] - acc[0]);
  for (int a = 0; a < Dim; ++a) {
    v[a] = acc[2 + a] / m_eff;
    f[a] = acc[2 + Dim + a];
  }
  Vec<Dim> vn = v + dt / m_eff * f;
  constrain_node(i, vn);
  grid_v_[i] = v;
  grid_v_new_[i] = vn;
  return lambda > 0.0;
}

template <int Dim>
void MpmSolver<Dim>::mirror_ghost(size_t g) {
  const NodeConstraint<Dim>& con = ghosts_[g];
  Vec<Dim> vm = Vec<Dim>::Zero(), vo = Vec<Dim>::Zero();
  for (int k = 0; k < con.mirror_count; ++k) {
    // A shared node's value is a momentum share rather than a velocity: it counts 1 − λ.
    const double w = con.mirror_weights[k] * (1.0 - grid_share_[con.mirror_nodes[k]]);
    vm += w * grid_v_new_[con.mirror_nodes[k]];
    vo += w * grid_v_[con.mirror_nodes[k]];
  }
  ghost_v_[g] = reflect_at_wall<Dim>(con, vo);
  ghost_v_new_[g] = reflect_at_wall<Dim>(con, vm);
}

template <int Dim>
void MpmSolver<Dim>::particles_to_grid(double dt) {
  const int32_t P = particles_.size();
  const int32_t N = bg_.num_nodes();
  const bool apic = settings_.transfer == Transfer::kApic;
  const bool simplicial = !bg_.grid;
  Failure failure;
  // Kernel evaluation and P2G into per-thread buffers (no races), then a reduction over nodes.
  constexpr int kStride = 2 + 2 * Dim;  // mass, Σ |w| m_p, momentum, force
  const int threads = omp_get_max_threads();
  int64_t shared_nodes = 0;
  if (static_cast<int64_t>(scatter_.size()) < static_cast<int64_t>(threads) * N * kStride)
    scatter_.resize(static_cast<size_t>(threads) * N * kStride);
#pragma omp parallel num_threads(threads)
  {
    const int tid = omp_get_thread_num();
    double* buf = scatter_.data() + static_cast<size_t>(tid) * N * kStride;
    std::fill(buf, buf + static_cast<size_t>(N) * kStride, 0.0);
#pragma omp for schedule(static)
    for (int32_t p = 0; p < P; ++p) {
      KernelEntry<Dim>* e = entries_.data() + entry_offsets_[p];
      const Vec<Dim>& xp = particles_.x[p];
      const int n = simplicial ? kernel_.evaluate_in_cell(xp, cell_[p], bary_[p], e)
                               : kernel_.evaluate(xp, cell_[p], e);
      if (n < 0) {
        failure.record(p, kernel_failure<Dim>(n, xp));
        entry_counts_[p] = 0;
        continue;
      }
      entry_counts_[p] = n;
      const double mp = particles_.mass[p];
      const Mat<Dim> stress_volume =
          sigma_[p] * (particles_.volume0[p] * particles_.F[p].determinant());
      Mat<Dim> affine = Mat<Dim>::Zero();
      if (apic) affine = apic_affine(p, e, n);
      affine_[p] = affine;
      const Vec<Dim> gravity_force = mp * settings_.gravity;
      for (int i = 0; i < n; ++i) {
        double* node = buf + static_cast<size_t>(e[i].node) * kStride;
        const double wm = e[i].w * mp;
        Vec<Dim> momentum = particles_.v[p];
        if (apic) momentum.noalias() += affine * (bg_.points[e[i].node] - xp);
        const Vec<Dim> force = e[i].w * gravity_force - stress_volume * e[i].grad;
        node[0] += wm;
        node[1] += std::abs(wm);
        for (int a = 0; a < Dim; ++a) {
          node[2 + a] += wm * momentum[a];
          node[2 + Dim + a] += force[a];
        }
      }
    }
    // Reduction and grid update (symplectic Euler + constraints), parallel over nodes.
    int64_t shared_here = 0;
#pragma omp for schedule(static) nowait
    for (int32_t i = 0; i < N; ++i) {
      double acc[kStride];
      for (int k = 0; k < kStride; ++k) acc[k] = scatter_[static_cast<size_t>(i) * kStride + k];
      for (int t = 1; t < threads; ++t)
        for (int k = 0; k < kStride; ++k)
          acc[k] += scatter_[(static_cast<size_t>(t) * N + i) * kStride + k];
      if (update_node(i, acc, dt)) ++shared_here;
    }
#pragma omp atomic
    shared_nodes += shared_here;
#pragma omp barrier
    // Ghost nodes mirror the (already constrained) velocities at their reflected points.
#pragma omp for schedule(static)
    for (size_t g = 0; g < ghosts_.size(); ++g) mirror_ghost(g);
#pragma omp for schedule(static)
    for (size_t g = 0; g < ghosts_.size(); ++g) {
      if (!ghost_writes_[g]) continue;  // a later ghost of the same node writes it (no race)
      grid_v_[ghosts_[g].node] = ghost_v_[g];
      grid_v_new_[ghosts_[g].node] = ghost_v_new_[g];
      grid_share_[ghosts_[g].node] = 0.0;  // a velocity again (walls do not conserve momentum)
    }
  }
  if (failure.failed()) fail(failure.particle, failure.cause);
  shared_node_steps_ += shared_nodes;
}

template <int Dim>
void MpmSolver<Dim>::grid_to_particles(double dt) {
  const int32_t P = particles_.size();
  const bool apic = settings_.transfer == Transfer::kApic;
  Failure failure;
  // G2P, deformation update, checks and stresses.
  const double flip = settings_.flip_ratio;
#pragma omp parallel for schedule(static)
  for (int32_t p = 0; p < P; ++p) {
    const KernelEntry<Dim>* e = entries_.data() + entry_offsets_[p];
    const int n = entry_counts_[p];
    const Vec<Dim> xp = particles_.x[p];
    Vec<Dim> v_pic = Vec<Dim>::Zero(), dv = Vec<Dim>::Zero();
    Mat<Dim> grad_v = Mat<Dim>::Zero(), B = Mat<Dim>::Zero();
    for (int i = 0; i < n; ++i) {
      const int32_t node = e[i].node;
      const Vec<Dim>& vi = grid_v_new_[node];
      const Vec<Dim> r = bg_.points[node] - xp;
      // A shared node (λ > 0, see the grid update) pays back with w + λ (|w| − w); in the
      // velocity gradient its value counts 1 − λ, the particle's own affine field the rest.
      const double lambda = grid_share_[node];
      const double w = e[i].w + lambda * (std::abs(e[i].w) - e[i].w);
      v_pic.noalias() += w * vi;
      if (lambda > 0.0) {
        const Vec<Dim> own = particles_.v[p] + affine_[p] * r;
        grad_v.noalias() += ((1.0 - lambda) * vi + lambda * own) * e[i].grad.transpose();
      } else {
        grad_v.noalias() += vi * e[i].grad.transpose();
      }
      if (apic) {
        B.noalias() += w * vi * r.transpose();
      } else {
        dv.noalias() += w * (vi - grid_v_[node]);
      }
    }
    if (apic) {
      particles_.v[p] = v_pic;
      particles_.B[p] = B;
    } else {
      particles_.v[p] = flip * (particles_.v[p] + dv) + (1.0 - flip) * v_pic;
    }
    particles_.x[p] = xp + dt * v_pic;
    const Mat<Dim> F = (Mat<Dim>::Identity() + dt * grad_v) * particles_.F[p];
    particles_.F[p] = F;
    const double J = F.determinant();
    if (!all_finite<Dim>(particles_.x[p]) || !all_finite<Dim>(particles_.v[p]) || !F.allFinite()) {
      failure.record(p, "NaN or infinite state (position, velocity or deformation gradient)");
      continue;
    }
    if (!(J > 0.0)) {
      failure.record(p, "inverted (J = " + std::to_string(J) + " <= 0)");
      continue;
    }
    // Plastic correction of the particle's own F_e and α (isochoric: J is unchanged).
    j2_return_map<Dim>(materials_[particles_.material[p]], particles_.F[p],
                       particles_.plastic_strain[p]);
    update_stress(p);
    const double eta = materials_[particles_.material[p]].viscosity;
    if (eta > 0.0) sigma_[p] += eta * (grad_v + grad_v.transpose());
    if (!sigma_[p].allFinite()) failure.record(p, "NaN stress");
  }
  if (failure.failed()) fail(failure.particle, failure.cause);
}

template <int Dim>
Diagnostics<Dim> MpmSolver<Dim>::diagnostics() const {
  Diagnostics<Dim> d;
  for (int32_t p = 0; p < particles_.size(); ++p) {
    const double m = particles_.mass[p];
    const Vec<Dim>& x = particles_.x[p];
    const Vec<Dim>& v = particles_.v[p];
    const Mat<Dim>& B = particles_.B[p];
    d.kinetic += 0.5 * m * v.squaredNorm();
    d.elastic += particles_.volume0[p] * psi_[p];
    d.gravitational -= m * settings_.gravity.dot(x);
    d.momentum += m * v;
    if constexpr (Dim == 2) {
      d.angular[0] += m * (x[0] * v[1] - x[1] * v[0] + B(1, 0) - B(0, 1));
    } else {
      const Vec<3> lin = x.cross(v);
      const Vec<3> aff(B(2, 1) - B(1, 2), B(0, 2) - B(2, 0), B(1, 0) - B(0, 1));
      d.angular += m * (lin + aff);
    }
  }
  return d;
}

template struct Particles<2>;
template struct Particles<3>;
template class MpmSolver<2>;
template class MpmSolver<3>;

}  // namespace bsms::mpm
