// DeepMind's MeshGraphNets datasets as distributed (docs/design.md "Public datasets"): a folder
// with `meta.json` and `{train,valid,test}.tfrecord`.
//
// TFRecord framing, per record: uint64 LE length, uint32 masked CRC32C of those 8 bytes, data,
// uint32 masked CRC32C of the data. One record is one trajectory, a tf.train.Example whose feature
// map holds, per field of meta `field_names`, a BytesList with one raw little-endian byte string,
// decoded by the field's meta `dtype` and reshaped by its meta `shape` (-1 = node or cell count;
// static fields are [1, N, d], dynamic ones [T, N, d], dynamic_varlen ones carry a companion
// `length_<field>` with the rows of each frame).
//
// Opening a file scans record headers only. A record's protobuf wire is walked on first access,
// reading tags, keys and lengths only (a few blocks per record, however large it is), which
// records where each field's bytes lie; reads fetch only those bytes. The data CRC covers the
// whole record, so it is checked (the record read once, whole) on the first read of a dynamic
// field or by decode(): the static mesh of every trajectory can be read without a pass over a
// 13 GB split. Every problem is an InputError naming the file, the record and the field.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "data/dataset/tfrecord_meta.hpp"

namespace bsms::tfrecord {

// CRC32C (Castagnoli), extending `crc` (0 to start). Uses SSE4.2 when the build has it.
uint32_t crc32c(const void* data, size_t size, uint32_t crc = 0);
// The table version (always compiled; what crc32c uses without SSE4.2).
uint32_t crc32c_portable(const void* data, size_t size, uint32_t crc = 0);
// TFRecord's masked CRC: ((crc >> 15) | (crc << 17)) + 0xa282ead8.
uint32_t mask_crc(uint32_t crc);

// Where one field of a record lies, after the record was checked and walked.
struct FieldSlice {
  uint64_t offset = 0;               // offset of the raw bytes in the file (or memory image)
  uint64_t bytes = 0;                // length of the raw bytes
  int64_t count = 0;                 // the -1 dimension (N or C); varlen: total rows
  std::vector<int64_t> shape;        // the meta shape with -1 resolved (varlen: left -1)
  std::vector<int64_t> row_lengths;  // dynamic_varlen: rows per frame ([T])
  int64_t frames() const { return shape.empty() ? 1 : shape[0]; }
};

struct RecordLayout {
  std::vector<FieldSlice> fields;  // same order as Meta::fields
  int64_t num_nodes = -1;          // N shared by every fixed-size field but cells; -1: none
};

// A whole field of a record in memory (float dtypes in `floats`, integer ones in `ints`).
struct DecodedField {
  std::vector<int64_t> shape;  // resolved (varlen: -1 left in place)
  std::vector<float> floats;
  std::vector<int64_t> ints;
  std::vector<int64_t> row_lengths;
};

// The static mesh of a record: mesh_pos [N, dim], cells [C, cell_size], node_type [N].
struct MeshArrays {
  int dim = 0;
  int cell_size = 0;
  std::vector<float> mesh_pos;
  std::vector<int32_t> cells;
  std::vector<int32_t> node_type;
};

// One .tfrecord file (or an in-memory image of one) read under a Meta. Thread-safe.
class TfRecordReader {
 public:
  // Scans the record headers of `path` (checks the length CRCs; never reads record data).
  TfRecordReader(const std::string& path, Meta meta);
  // The same from bytes in memory; `name` labels messages (fuzzing, tests).
  static TfRecordReader from_bytes(std::string bytes, const std::string& name, Meta meta);
  ~TfRecordReader();
  TfRecordReader(TfRecordReader&&) noexcept;
  TfRecordReader& operator=(TfRecordReader&&) noexcept;

  const std::string& path() const;
  const Meta& meta() const;
  int64_t num_records() const;
  uint64_t record_bytes(int64_t record) const;  // data length of a record

  // Walks the wire of a record on first call (then cached; no CRC check): every field present,
  // sizes that fit dtype and shape, N consistent.
  const RecordLayout& layout(int64_t record) const;
  // Frames [t0, t0 + count) of a fixed-size field as float: [count, N, width] flattened (static
  // fields have one frame). Reads only those bytes (and, for a dynamic field, the whole record
  // once for its CRC).
  std::vector<float> read_float(int64_t record, const std::string& field, int64_t t0,
                                int64_t count) const;
  // A whole integer field as int32 (int64 values must fit).
  std::vector<int32_t> read_int32(int64_t record, const std::string& field) const;
  // mesh_pos, cells and node_type of a record, checked: finite positions, cells in range.
  MeshArrays read_mesh(int64_t record) const;
  // Reads, checks and converts a whole record in one pass (benchmarks, tests, fuzzing).
  std::map<std::string, DecodedField> decode(int64_t record) const;

 private:
  TfRecordReader();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bsms::tfrecord
