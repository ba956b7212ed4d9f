// meta.json of a DeepMind MeshGraphNets dataset folder (tfrecord.hpp reads the records under it):
// per field of `field_names`, its kind (static, dynamic, dynamic_varlen), dtype and shape (-1 =
// node or cell count), plus trajectory_length, dt, collision_radius and simulator. Every problem
// is an InputError naming the file and the field.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace bsms::tfrecord {

enum class DType { kFloat32, kFloat64, kInt32, kInt64 };
enum class FieldKind { kStatic, kDynamic, kDynamicVarlen };

const char* dtype_name(DType dtype);    // "float32", ...
const char* kind_name(FieldKind kind);  // "static", "dynamic", "dynamic_varlen"
size_t dtype_size(DType dtype);         // bytes per value
std::string shape_string(const std::vector<int64_t>& shape);  // "[24,-1,2]"

struct FieldSpec {
  std::string name;
  FieldKind kind = FieldKind::kStatic;
  DType dtype = DType::kFloat32;
  std::vector<int64_t> shape;          // meta shape; at most one -1 (the node or cell count)
  DType length_dtype = DType::kInt32;  // dynamic_varlen: dtype of `length_<name>`
  int64_t width() const { return shape.empty() ? 1 : (shape.back() < 0 ? 1 : shape.back()); }
};

// meta.json of a MeshGraphNets dataset folder.
struct Meta {
  std::string path;               // the meta.json file (for messages)
  std::vector<FieldSpec> fields;  // in field_names order (varlen companions not listed)
  int64_t trajectory_length = 0;  // frames per trajectory (T)
  double dt = 0.0;                // seconds between frames (0 when absent)
  double collision_radius = 0.0;  // 0 when null or absent
  std::string simulator;          // "" when absent
  const FieldSpec* find(const std::string& name) const;  // nullptr when not a field
};

// Parses meta.json text; `path` names it in messages. Throws InputError.
Meta parse_meta(const std::string& text, const std::string& path);
Meta read_meta(const std::string& path);

}  // namespace bsms::tfrecord
