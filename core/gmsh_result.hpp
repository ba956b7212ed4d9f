// What the gmsh worker (gmsh_worker.hpp) hands back to bsms: a Mesh, or the error that stopped
// it, in one file written at the end of its work. The layout is private to one build (native byte
// order, no versioning beyond the magic): the worker and bsms come from the same build.
//
//   "BSMSGMW1", u32 status, u32 0
//   status Mesh:  i32 dim, i32 cell_dim, i64 N, i64 C, u64 groups,
//                 f64[N*dim] points, i64[C*(cell_dim+1)] cells, i64[N] node tags,
//                 per group: u64 name length, name, u64 count, i64[count] node indices
//   otherwise:    u64 length, message
//   "BSMSEND1"
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "core/mesh.hpp"

namespace bsms {

struct GmshResult {
  enum class Status : uint32_t {
    Mesh = 0,         // `mesh` holds the result
    InputError = 1,   // `message`: the InputError the reading threw (it names the file)
    OutOfMemory = 2,  // `message`: where the memory limit stopped it
    Failure = 3,      // `message`: any other exception
  };
  Status status = Status::Mesh;
  std::string message;
  Mesh mesh;
};

// Writes `result` to the file descriptor `fd` (all of it, retrying short writes). False when a
// write fails (errno is kept).
bool write_gmsh_result(int fd, const GmshResult& result);

// Reads a result back. Throws std::runtime_error naming what is wrong when `bytes` is not one
// whole result (cut short, trailing bytes, sizes beyond the bytes, indices out of range).
GmshResult parse_gmsh_result(std::string_view bytes);

}  // namespace bsms
