#include "data/dataset/tfrecord_meta.hpp"

#include <nlohmann/json.hpp>

#include "core/config.hpp"
#include "core/error.hpp"

namespace bsms::tfrecord {

const char* dtype_name(DType dtype) {
  switch (dtype) {
    case DType::kFloat32:
      return "float32";
    case DType::kFloat64:
      return "float64";
    case DType::kInt32:
      return "int32";
    case DType::kInt64:
      return "int64";
  }
  return "?";
}

const char* kind_name(FieldKind kind) {
  switch (kind) {
    case FieldKind::kStatic:
      return "static";
    case FieldKind::kDynamic:
      return "dynamic";
    case FieldKind::kDynamicVarlen:
      return "dynamic_varlen";
  }
  return "?";
}

size_t dtype_size(DType dtype) {
  return (dtype == DType::kFloat32 || dtype == DType::kInt32) ? 4 : 8;
}

std::string shape_string(const std::vector<int64_t>& shape) {
  std::string s = "[";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? "," : "") + std::to_string(shape[i]);
  return s + "]";
}

const FieldSpec* Meta::find(const std::string& name) const {
  for (const auto& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

namespace {

constexpr int64_t kMaxElements = int64_t{1} << 48;

DType parse_dtype(std::string s, const std::string& where) {
  // One published meta.json spells it "<dtype: 'float32'>".
  const std::string prefix = "<dtype: '", suffix = "'>";
  if (s.size() > prefix.size() + suffix.size() && s.compare(0, prefix.size(), prefix) == 0 &&
      s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0)
    s = s.substr(prefix.size(), s.size() - prefix.size() - suffix.size());
  if (s == "float32") return DType::kFloat32;
  if (s == "float64") return DType::kFloat64;
  if (s == "int32") return DType::kInt32;
  if (s == "int64") return DType::kInt64;
  throw InputError(where + ": unknown dtype '" + truncate_for_message(s) +
                   "' (expected float32, float64, int32 or int64)");
}

// The value of a key the meta file must have.
const Json& required_key(const Json& j, const char* key, const std::string& path) {
  if (!j.contains(key)) throw InputError(path + ": missing key '" + key + "'");
  return j.at(key);
}

// trajectory_length, and the optional dt, collision_radius and simulator.
void parse_scalars(const Json& j, const std::string& path, Meta& m) {
  const Json& length = required_key(j, "trajectory_length", path);
  if (!length.is_number_integer() || length.get<int64_t>() < 1 ||
      length.get<int64_t>() > (int64_t{1} << 31))
    throw InputError(path + ": 'trajectory_length' must be a positive integer");
  m.trajectory_length = length.get<int64_t>();
  if (j.contains("dt") && !j["dt"].is_null()) {
    if (!j["dt"].is_number() || !std::isfinite(j["dt"].get<double>()) || j["dt"].get<double>() < 0)
      throw InputError(path + ": 'dt' must be a non-negative number");
    m.dt = j["dt"].get<double>();
  }
  if (j.contains("collision_radius") && !j["collision_radius"].is_null()) {
    const Json& r = j["collision_radius"];
    if (!r.is_number() || !std::isfinite(r.get<double>()) || r.get<double>() < 0)
      throw InputError(path + ": 'collision_radius' must be a non-negative number or null");
    m.collision_radius = r.get<double>();
  }
  if (j.contains("simulator") && !j["simulator"].is_null()) {
    if (!j["simulator"].is_string()) throw InputError(path + ": 'simulator' must be a string");
    m.simulator = j["simulator"].get<std::string>();
  }
}

FieldKind parse_kind(const std::string& type, const std::string& where) {
  if (type == "static") return FieldKind::kStatic;
  if (type == "dynamic") return FieldKind::kDynamic;
  if (type == "dynamic_varlen") return FieldKind::kDynamicVarlen;
  throw InputError(where + ": unknown type '" + truncate_for_message(type) +
                   "' (expected static, dynamic or dynamic_varlen)");
}

// Reads f.shape and checks it against f.kind and the trajectory length.
void parse_shape(const Json& shape, const std::string& where, int64_t trajectory_length,
                 FieldSpec& f) {
  if (!shape.is_array() || shape.empty() || shape.size() > 8)
    throw InputError(where + ": 'shape' must be a list of 1 to 8 integers");
  int unknown = 0;
  int64_t known = 1;
  for (const Json& e : shape) {
    if (!e.is_number_integer())
      throw InputError(where + ": 'shape' must be a list of 1 to 8 integers");
    const int64_t v = e.get<int64_t>();
    if (v == -1) {
      ++unknown;
    } else if (v < 1 || v > kMaxElements || known > kMaxElements / v) {
      throw InputError(where + ": shape entry " + std::to_string(v) +
                       " out of range (positive, or -1 for the node/cell count)");
    } else {
      known *= v;
    }
    f.shape.push_back(v);
  }
  if (unknown > 1)
    throw InputError(where + ": shape " + shape_string(f.shape) + " has more than one -1");
  if (f.kind == FieldKind::kStatic && f.shape[0] != 1)
    throw InputError(where + ": static shape " + shape_string(f.shape) + " must start with 1");
  if (f.kind != FieldKind::kStatic && f.shape[0] != trajectory_length)
    throw InputError(where + ": dynamic shape " + shape_string(f.shape) +
                     " must start with trajectory_length " + std::to_string(trajectory_length));
  if (f.kind == FieldKind::kDynamicVarlen &&
      (unknown != 1 || f.shape.size() < 2 || f.shape[1] != -1))
    throw InputError(where + ": dynamic_varlen shape " + shape_string(f.shape) +
                     " must be [T,-1,...]");
}

// The field listed by name_json in field_names, described in features; m holds the fields so far.
FieldSpec parse_field(const Json& name_json, const Json& features, const Meta& m,
                      const std::string& path) {
  if (!name_json.is_string())
    throw InputError(path + ": 'field_names' must be a non-empty list of strings");
  FieldSpec f;
  f.name = name_json.get<std::string>();
  const std::string where = path + ": field '" + truncate_for_message(f.name) + "'";
  if (m.find(f.name)) throw InputError(where + " is listed twice in 'field_names'");
  if (!features.contains(f.name)) throw InputError(where + " has no entry in 'features'");
  const Json& spec = features.at(f.name);
  if (!spec.is_object()) throw InputError(where + ": expected an object");
  for (const char* key : {"type", "shape", "dtype"})
    if (!spec.contains(key)) throw InputError(where + ": missing key '" + key + "'");
  if (!spec["type"].is_string() || !spec["dtype"].is_string())
    throw InputError(where + ": 'type' and 'dtype' must be strings");
  f.kind = parse_kind(spec["type"].get<std::string>(), where);
  f.dtype = parse_dtype(spec["dtype"].get<std::string>(), where);
  parse_shape(spec["shape"], where, m.trajectory_length, f);
  return f;
}

// `length_<field>` companions of varlen fields are read with their field, never on their own:
// their dtype goes to the field and they leave the field list.
void attach_length_companions(const Json& features, const std::vector<std::string>& varlen,
                              const std::string& path, Meta& m) {
  for (const auto& name : varlen) {
    const std::string companion = "length_" + name;
    DType dtype = DType::kInt32;
    if (features.contains(companion) && features.at(companion).is_object() &&
        features.at(companion).contains("dtype") && features.at(companion)["dtype"].is_string())
      dtype = parse_dtype(features.at(companion)["dtype"].get<std::string>(),
                          path + ": field '" + truncate_for_message(companion) + "'");
    if (dtype != DType::kInt32 && dtype != DType::kInt64)
      throw InputError(path + ": field '" + truncate_for_message(companion) +
                       "': row lengths must be int32 or int64");
    for (size_t i = 0; i < m.fields.size(); ++i)
      if (m.fields[i].name == companion) {
        m.fields.erase(m.fields.begin() + static_cast<std::ptrdiff_t>(i));
        break;
      }
    for (auto& f : m.fields)
      if (f.name == name) f.length_dtype = dtype;
  }
}

}  // namespace

Meta parse_meta(const std::string& text, const std::string& path) {
  // The one bounded JSON reader (core/config.hpp): nesting depth, duplicate keys.
  const Json j = parse_json_text(text, path);
  if (!j.is_object()) throw InputError(path + ": expected a JSON object, got " + describe_json(j));
  Meta m;
  m.path = path;
  parse_scalars(j, path, m);
  const Json& names = required_key(j, "field_names", path);
  const Json& features = required_key(j, "features", path);
  // Published datasets have a handful; the bound keeps the checks below linear in practice.
  constexpr size_t kMaxFields = 256;
  if (!names.is_array() || names.empty() || names.size() > kMaxFields)
    throw InputError(path + ": 'field_names' must be a non-empty list of at most " +
                     std::to_string(kMaxFields) + " strings");
  if (!features.is_object()) throw InputError(path + ": 'features' must be an object");
  std::vector<std::string> varlen;
  for (const Json& name_json : names) {
    FieldSpec f = parse_field(name_json, features, m, path);
    if (f.kind == FieldKind::kDynamicVarlen) varlen.push_back(f.name);
    m.fields.push_back(std::move(f));
  }
  attach_length_companions(features, varlen, path, m);
  return m;
}

Meta read_meta(const std::string& path) {
  return parse_meta(
      read_text_file(path, kMaxJsonBytes, "meta.json (a MeshGraphNets dataset needs it)"), path);
}

}  // namespace bsms::tfrecord
