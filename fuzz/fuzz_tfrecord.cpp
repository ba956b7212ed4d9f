// libFuzzer target for the MeshGraphNets reader: the input is a .tfrecord image
// read under a fixed meta.json (CylinderFlow's fields), or, when it starts with '{', a meta.json
// text. Every record is indexed, walked and decoded; InputError is the only allowed outcome of
// bad bytes. Built with -DBSMS_FUZZ=ON and clang (`make fuzz`).
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.hpp"
#include "data/dataset/tfrecord.hpp"

namespace {

const bsms::tfrecord::Meta& cylinder_meta() {
  static const bsms::tfrecord::Meta meta = bsms::tfrecord::parse_meta(
      R"({"trajectory_length": 3, "dt": 0.01, "collision_radius": null,
          "field_names": ["cells", "mesh_pos", "node_type", "velocity", "pressure"],
          "features": {
            "cells": {"type": "static", "shape": [1, -1, 3], "dtype": "int32"},
            "mesh_pos": {"type": "static", "shape": [1, -1, 2], "dtype": "float32"},
            "node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"},
            "velocity": {"type": "dynamic", "shape": [3, -1, 2], "dtype": "float32"},
            "pressure": {"type": "dynamic", "shape": [3, -1, 1], "dtype": "<dtype: 'float32'>"}}})",
      "fuzz/meta.json");
  return meta;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    if (!bytes.empty() && bytes[0] == '{') {
      const auto meta = bsms::tfrecord::parse_meta(bytes, "fuzz/meta.json");
      (void)meta;
      return 0;
    }
    auto reader = bsms::tfrecord::TfRecordReader::from_bytes(std::move(bytes), "fuzz.tfrecord",
                                                             cylinder_meta());
    for (int64_t r = 0; r < reader.num_records(); ++r) {
      try {
        reader.decode(r);
        reader.read_mesh(r);
        reader.read_float(r, "velocity", 1, 2);
      } catch (const bsms::InputError&) {
      }
    }
  } catch (const bsms::InputError&) {
  }
  return 0;
}
