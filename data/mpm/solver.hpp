// Explicit MPM (thesis Algorithm 1) with APIC or FLIP transfers, symplectic Euler, CFL time step,
// gravity, Dirichlet / roller / slip node constraints and any of the transfer kernels. Units: SI.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "data/mpm/background.hpp"
#include "data/mpm/kernel.hpp"
#include "data/mpm/material.hpp"

namespace bsms::mpm {

enum class Transfer { kApic, kFlip };
std::string to_string(Transfer transfer);
Transfer parse_transfer(const std::string& name, const std::string& where);  // "apic" | "flip"

// fixed: v = 0; roller: v·n = 0; slip: v·n ≤ 0 (the body may leave the wall). A roller or slip node
// without a normal is treated as fixed.
enum class BoundaryType { kFixed, kRoller, kSlip };
std::string to_string(BoundaryType type);
BoundaryType parse_boundary_type(const std::string& name, const std::string& where);

// A constrained node. Nodes on the wall get the condition directly. Ghost nodes beyond the wall
// (mirror_count > 0) get the mirror image of the velocity interpolated at their reflection
// inside the domain (fixed: −v; roller: v − 2(v·n)n; slip: reflected only while approaching), so
// the condition holds on the wall itself rather than one layer further out.
template <int Dim>
struct NodeConstraint {
  int32_t node = 0;
  BoundaryType type = BoundaryType::kFixed;
  Vec<Dim> normal = Vec<Dim>::Zero();  // outward unit normal of the wall
  int mirror_count = 0;
  std::array<int32_t, Dim + 1> mirror_nodes{};
  std::array<double, Dim + 1> mirror_weights{};
};

// Particle state, structure of arrays, [P] each.
template <int Dim>
struct Particles {
  std::vector<Vec<Dim>> x;        // position, m
  std::vector<Vec<Dim>> v;        // velocity, m/s
  std::vector<Mat<Dim>> F;        // deformation gradient (elastic part F_e for hencky_j2)
  std::vector<Mat<Dim>> B;        // APIC affine matrix Σ w v_i (x_i − x_p)ᵀ, m²/s
  std::vector<double> mass;       // kg
  std::vector<double> volume0;    // m³ (reference)
  std::vector<int32_t> material;  // index into the solver's materials
  std::vector<int32_t> body;      // body index
  // hencky_j2: equivalent plastic strain α (dimensionless); stays 0 for elastic models. An empty
  // array (particles built by hand) is sized to zeros by the solver.
  std::vector<double> plastic_strain;
  int32_t size() const { return static_cast<int32_t>(x.size()); }
  void resize(int32_t n);
};

template <int Dim>
struct SolverSettings {
  KernelType kernel = KernelType::kUmls;
  Transfer transfer = Transfer::kApic;
  double cfl = 0.3;                     // dt = cfl * spacing / (c + |v|max)
  double fixed_dt = 0.0;                // > 0: use this time step (s) instead of the CFL one
  double flip_ratio = 1.0;              // FLIP share of the FLIP/PIC blend (1 = pure FLIP)
  Vec<Dim> gravity = Vec<Dim>::Zero();  // m/s²
};

// Totals over particles. Angular momentum includes the APIC affine term Σ m (Bᵀ : ε).
template <int Dim>
struct Diagnostics {
  static constexpr int kAngular = Dim == 2 ? 1 : 3;
  double kinetic = 0.0, elastic = 0.0, gravitational = 0.0;  // J
  Vec<Dim> momentum = Vec<Dim>::Zero();                      // kg m/s
  Eigen::Matrix<double, kAngular, 1> angular = Eigen::Matrix<double, kAngular, 1>::Zero();
};

template <int Dim>
class MpmSolver {
 public:
  MpmSolver(BackgroundMesh<Dim> background, std::vector<Material> materials,
            Particles<Dim> particles, std::vector<NodeConstraint<Dim>> constraints,
            SolverSettings<Dim> settings);

  // CFL time step for the current state, s.
  double stable_dt() const;
  // One explicit step of length dt (s). Throws NumericalError naming the step, the particle and
  // the cause (NaN, J ≤ 0, particle outside the mesh, degenerate kernel); the state is then
  // invalid.
  void step(double dt);
  // Steps (CFL or fixed dt) until time t, landing on t exactly.
  void advance_to(double t);

  Diagnostics<Dim> diagnostics() const;
  const Particles<Dim>& particles() const { return particles_; }
  // Replaces particle p's velocity (m/s) between steps, e.g. to perturb a state in an experiment on
  // the solver's own predictability. Under APIC the affine matrix B is kept as it was.
  void set_velocity(int32_t p, const Vec<Dim>& v) { particles_.v.at(static_cast<size_t>(p)) = v; }
  const BackgroundMesh<Dim>& background() const { return bg_; }
  const TransferKernel<Dim>& kernel() const { return kernel_; }
  std::vector<double> von_mises_stress() const;  // [P], Pa
  double time() const { return time_; }
  int64_t steps() const { return steps_; }
  double max_wave_speed() const { return max_wave_speed_; }
  // Node-steps so far in which negative MLS weights cancelled most of a node's mass, so that the
  // node paid its momentum back by |w| (see update_node()); a count, for tests and reports.
  int64_t shared_node_steps() const { return shared_node_steps_; }

 private:
  // The phases of step(), in order; each throws through fail() on the first bad particle.
  // Locates the particles and sizes their kernel slots (entry_offsets_, entries_).
  void locate_particles();
  // Evaluates the kernels, scatters mass, momentum and force to the nodes, reduces them and
  // updates the grid velocities (symplectic Euler, constraints, ghost mirrors).
  void particles_to_grid(double dt);
  // Gathers the grid velocities back, moves the particles, updates F, plasticity and stress.
  void grid_to_particles(double dt);
  // APIC affine velocity B D⁻¹ of particle p over its n kernel entries e, 1/s (zero where D is
  // singular).
  Mat<Dim> apic_affine(int32_t p, const KernelEntry<Dim>* e, int n) const;
  // Grid update of node i from its reduced scatter values acc = [mass, Σ |w| m_p, momentum (Dim),
  // force (Dim)]: mass, velocity, share λ and the constrained new velocity after dt. Returns
  // whether the node is shared (λ > 0).
  bool update_node(int32_t i, const double* acc, double dt);
  // Applies node i's constraints to its new velocity vn.
  void constrain_node(int32_t i, Vec<Dim>& vn) const;
  // Ghost g's mirror image of the constrained grid velocities, staged in ghost_v_, ghost_v_new_.
  void mirror_ghost(size_t g);
  void update_stress(int32_t p);
  [[noreturn]] void fail(int32_t particle, const std::string& cause) const;

  BackgroundMesh<Dim> bg_;
  TransferKernel<Dim> kernel_;
  std::vector<Material> materials_;
  Particles<Dim> particles_;
  SolverSettings<Dim> settings_;
  std::vector<int32_t> constraint_offsets_;       // [N + 1] CSR over nodes
  std::vector<NodeConstraint<Dim>> constraints_;  // all constrained nodes, by node (CSR)
  std::vector<NodeConstraint<Dim>> ghosts_;       // ghost nodes, mirrored after the others
  // Per ghost: 1 when no later ghost has its node (a corner node can be a ghost of two walls;
  // the last one's image stands, as in a serial loop, whatever the thread count).
  std::vector<uint8_t> ghost_writes_;
  double max_wave_speed_ = 0.0;
  double max_kinematic_viscosity_ = 0.0;  // max η / ρ over the materials, m²/s
  double time_ = 0.0;
  int64_t steps_ = 0;
  int64_t shared_node_steps_ = 0;

  // Per-particle state derived each step.
  std::vector<int32_t> cell_;                            // walk hints
  std::vector<Eigen::Matrix<double, Dim + 1, 1>> bary_;  // barycentric coordinates in cell_
  std::vector<Mat<Dim>> sigma_;                          // Cauchy stress, Pa
  std::vector<double> psi_;                              // energy density, J/m³
  std::vector<int64_t> entry_offsets_;                   // [P + 1]
  std::vector<int32_t> entry_counts_;                    // [P]
  std::vector<KernelEntry<Dim>> entries_;
  // Grid: per-thread scatter buffers (mass, momentum, force per node) and reduced values.
  std::vector<double> scatter_;
  std::vector<double> grid_mass_;
  std::vector<Vec<Dim>> grid_v_, grid_v_new_;
  // λ in [0, 1] per node: > 0 where negative MLS weights cancel most of the node's mass; the
  // node's momentum is then paid back with weights w + λ (|w| − w) (see update_node()).
  std::vector<double> grid_share_;
  std::vector<Mat<Dim>> affine_;  // [P] APIC affine velocity C = B D⁻¹ of the last P2G, 1/s
  std::vector<Vec<Dim>> ghost_v_,
      ghost_v_new_;  // staging, so mirrors never read a ghost's new value
};

}  // namespace bsms::mpm
