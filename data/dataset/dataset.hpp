// Datasets of simulated trajectories (docs/design.md "Dataset"): one HDF5 file per split.
//
//   /                        attrs: format="bsms-dataset", version=1, scene (JSON), dim, frame_dt
//   /trajectories/<000000>/  attrs: seed, parameters (JSON)
//       cells int32 [C, dim+1], mesh_pos float32 [N, dim], node_type int32 [N], body_id int32 [N]
//       world_pos float32 [T, N, dim], velocity float32 [T, N, dim], stress float32 [T, N]
//       (optional)
//
// The reader also accepts the public datasets as users hold them (docs/design.md "Public
// datasets"):
// - DeepMind's MeshGraphNets folder `DIR/meta.json` + `DIR/{split}.tfrecord` (tfrecord.hpp);
// - the BSMS-GNN conversion to HDF5, a folder `{split}/` holding `{i}.h5`, each with mesh_pos,
//   cells, node_type and dynamic fields among world_pos, velocity, pressure, density (static
//   fields may carry a leading time axis);
// - the PyTorch ports' single `{split}.h5` with one group per trajectory ("0", "1", ...), each
//   laid out like one `{i}.h5` above.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "data/mpm/scene_config.hpp"

namespace bsms {

enum class NodeType : int32_t { kNormal = 0, kFixed = 1, kMoving = 2, kSlip = 3 };

// The time-independent part of a trajectory.
struct TrajectoryMesh {
  int dim = 0;                     // spatial dimension of mesh_pos
  int cell_size = 0;               // nodes per cell (dim + 1 for bsms data)
  std::vector<int32_t> cells;      // [C, cell_size]
  std::vector<float> mesh_pos;     // [N, dim] reference positions
  std::vector<int32_t> node_type;  // [N] NodeType values (public data: its own codes)
  std::vector<int32_t> body_id;    // [N] (all 0 when the data has no bodies)
  int64_t num_nodes() const { return static_cast<int64_t>(node_type.size()); }
  int64_t num_cells() const {
    return cell_size > 0 ? static_cast<int64_t>(cells.size()) / cell_size : 0;
  }
};

// A whole trajectory in memory, as the generator writes it.
struct Trajectory {
  TrajectoryMesh mesh;
  int64_t seed = 0;
  std::string parameters = "{}";  // JSON of the sampled scene parameters
  double solver_wall_s = -1.0;    // wall time the solver took for it (s); < 0: unknown
  int64_t num_frames = 0;
  // Dynamic fields by name: [T, N, width] flattened; width = dim for vectors, 1 for scalars.
  std::map<std::string, std::vector<float>> fields;
};

struct FieldInfo {
  std::string name;
  int64_t width = 0;  // components per node
};

// The root attributes that mark a bsms dataset file (format, version), and the static datasets of
// a trajectory: cells, mesh_pos, node_type, body_id (every other one is a field [T, N(, width)]).
constexpr const char* kDatasetFormat = "bsms-dataset";
constexpr int64_t kDatasetVersion = 1;
bool is_static_field(const std::string& name);

// The root attribute "scene" typed, as Dataset::parsed_scene holds it: none for "{}" (public
// data); a family file (an object with "scene", as `bsms generate` stores it) gives its base scene
// (mpm::parse_base_scene: the background, boundaries and gravity every draw shares); any other
// object is read as a scene file (mpm::parse_scene). InputError naming `source` (e.g. "FILE:
// attribute 'scene'") and the key when the text is malformed or its scene's dim is not `dim`.
std::optional<mpm::Scene> parse_dataset_scene(const std::string& text, int dim,
                                              const std::string& source);

// Bounds on the values a dataset may hold, checked where they are read (Dataset::mesh and
// Dataset::read; docs/hardening.md): |mesh_pos|, |world_pos| (m) and |velocity| (m/s) at most
// kPositionBound, every other field (stress, pressure, density) at most kFieldBound; NaN and
// infinity never. Real scenes are orders of magnitude inside them; a value beyond is damage or a
// units mistake, refused before it reaches training as an inf loss or a cast of 3e38.
constexpr double kPositionBound = 1e6;
constexpr double kFieldBound = 1e15;
// Node types of public data (MeshGraphNets codes 0..8), one-hot encoded with at most 64 classes.
constexpr int32_t kMaxPublicNodeType = 63;
double value_bound(const std::string& field);
// Throws InputError naming `where` (file and trajectory), the field, the first bad frame (when
// first_frame >= 0), node and component, unless every value is finite and within value_bound.
// `values` is [frames, nodes, width] flattened.
void check_field_values(const float* values, size_t count, int64_t nodes, int64_t width,
                        int64_t first_frame, const std::string& where, const std::string& field);

// The checks every dataset mesh passes where it is read (Dataset::mesh), for a mesh from elsewhere
// (the Python module's arrays): shapes, finite positions inside the bound, cells of distinct
// in-range nodes, node types in their set (NodeType when `simulated_node_types`, else public
// codes up to kMaxPublicNodeType), body ids >= 0. InputError prefixed with `where`.
void check_trajectory_mesh(const TrajectoryMesh& mesh, const std::string& where,
                           bool simulated_node_types);

// Writes a bsms dataset file atomically (temporary name, renamed by commit()); dataset_writer.cpp.
class DatasetWriter {
 public:
  DatasetWriter(const std::string& path, const std::string& scene_json, int dim, double frame_dt);
  ~DatasetWriter();
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  // Appends a trajectory under the next index (000000, 000001, ...). Rejects non-finite values
  // (never store NaN) and inconsistent shapes with an InputError.
  void add(const Trajectory& trajectory);
  // Completes the temporary file (root attributes, close, fsync) without renaming it; commit()
  // then only renames. Writers of several files that must appear together finish all first.
  void finish();
  void commit();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// How a split is stored (see the file comment).
enum class DatasetLayout {
  kBsms,              // DIR/{split}.h5 written by `bsms generate`
  kPublicFolder,      // DIR/{split}/{i}.h5 (BSMS-GNN converter output)
  kMeshGraphNets,     // DIR/meta.json + DIR/{split}.tfrecord (DeepMind, as distributed)
  kPublicSingleFile,  // DIR/{split}.h5 with one group per trajectory (PyTorch ports)
};
const char* layout_name(DatasetLayout layout);  // e.g. "MeshGraphNets TFRecord"

// Random access to (trajectory, frame) of one split, in any layout above; dataset.cpp.
class Dataset {
 public:
  // `location` is a bsms dataset file (e.g. DIR/train.h5), a single-file public {split}.h5, a
  // folder of public per-trajectory files (e.g. DIR/train/ holding 0.h5, 1.h5, ...) or a
  // MeshGraphNets DIR/{split}.tfrecord (meta.json beside it; only record headers are read here).
  // InputError names the file and the problem.
  explicit Dataset(const std::string& location);
  // Opens split `split` of a dataset folder: DIR/{split}.h5 if present, else DIR/{split}/, else
  // DIR/{split}.tfrecord with DIR/meta.json. BSMS-GNN's older DIR/outputs_{split}/ is rejected
  // with the conversion to run.
  static Dataset open_split(const std::string& dir, const std::string& split);
  // Whether `dir` holds the split (as open_split looks for it); says nothing of its contents.
  static bool has_split(const std::string& dir, const std::string& split);
  ~Dataset();
  Dataset(Dataset&&) noexcept;
  Dataset& operator=(Dataset&&) noexcept;

  const std::string& location() const;
  DatasetLayout layout() const;
  bool is_public_layout() const;  // every layout but kBsms
  // Node types are bsms's NodeType (simulated data), not public codes: what check_trajectory_mesh
  // checks this dataset's meshes against.
  bool has_simulated_node_types() const;
  // Spatial dimension of the dynamic positions: world_pos width when present, else mesh_pos
  // width (cloth: mesh_pos 2-D, world_pos 3-D; TrajectoryMesh::dim stays the mesh_pos width).
  int dim() const;
  double frame_dt() const;           // s; 0 when the data does not say
  double collision_radius() const;   // meta.json collision_radius; 0 when null or absent
  std::string simulator() const;     // meta.json "simulator" ("" when absent)
  const std::string& scene() const;  // scene JSON ("{}" for public data)
  // scene(), read strictly when the dataset opens (parse_dataset_scene; a malformed scene is an
  // InputError naming the file and the key); none when the data has none (public data).
  const std::optional<mpm::Scene>& parsed_scene() const;
  int64_t num_trajectories() const;
  int64_t num_frames(int64_t trajectory) const;
  std::vector<FieldInfo> fields() const;  // dynamic fields present in every trajectory
  bool has_field(const std::string& name) const;

  // Static mesh of a trajectory (read once, then cached).
  const TrajectoryMesh& mesh(int64_t trajectory) const;
  int64_t seed(int64_t trajectory) const;
  std::string parameters(int64_t trajectory) const;
  // Solver wall time of the trajectory in seconds, or a negative value when not recorded.
  double solver_wall_s(int64_t trajectory) const;
  // "FILE: trajectory T", the prefix of errors about one trajectory (FILE: its own file in a
  // public folder).
  std::string describe(int64_t trajectory) const;
  // Frames [t0, t0 + count) of a field: [count, N, width] flattened. The first read of a
  // trajectory checks every value of its dynamic fields (check_field_values), as mesh() checks
  // every mesh: InputError names the file, trajectory, field, frame and node.
  std::vector<float> read(int64_t trajectory, const std::string& field, int64_t t0,
                          int64_t count = 1) const;

 private:
  // Every value of every dynamic field of a trajectory, checked once (the first read of it).
  void check_trajectory(int64_t trajectory) const;
  std::vector<float> read_unchecked(int64_t trajectory, const std::string& field, int64_t t0,
                                    int64_t count, int64_t nodes) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bsms
