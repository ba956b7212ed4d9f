// libFuzzer targets for the mesh intake after gmsh. gmsh's file readers are
// not fuzzed (not bsms code); what bsms does with the arrays gmsh hands over is.
//   fuzz_mesh: make_mesh (validate_mesh) on decoded point and cell arrays, any dimension and
//     cell width, then find_bad_cells on what is accepted (the intake of dataset meshes).
//   fuzz_gmsh_mesh (BSMS_FUZZ_GMSH=1): nodes (tags, coordinates) and element blocks of gmsh types
//     (lines, triangles, tets, and unsupported second-order triangles and lines, quads) on
//     discrete curve, surface and volume entities are put into a gmsh model through its API;
//     GmshSession::extract_mesh (read_mesh's post-gmsh layer: top dimension, used nodes, tag
//     order, dim, validate_mesh) reads them back, then find_bad_cells. Not run by `make fuzz`:
//     libgmsh 4.8 corrupts its own heap after a few thousand models in one process (ASan
//     reports inside gmsh::clear / gmsh::finalize / getNodes, GEO_Internals and FieldManager,
//     with inputs that pass alone), even with a fresh gmsh per input (done here, ~20 inputs/s).
//     Physical groups, model points and point elements are not fed (they crashed it sooner).
// InputError is the only allowed outcome. Coordinates are small multiples of 1/4 (so that
// degenerate and inverted cells are common), NaN, or raw doubles; indices are small signed
// numbers or raw 64-bit values. Seeds: BSMS_FUZZ_WRITE_SEEDS=DIR <target> writes them to DIR.
#include <gmsh.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"
#include "core/mesh.hpp"
#include "seeds.hpp"

#ifndef BSMS_FUZZ_GMSH
#define BSMS_FUZZ_GMSH 0
#endif

namespace {

class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : p_(data), n_(size) {}
  uint8_t byte() { return i_ < n_ ? p_[i_++] : 0; }
  double coordinate() {
    const auto b = static_cast<int8_t>(byte());
    if (b == 127) return std::numeric_limits<double>::quiet_NaN();
    if (b == -128) {
      double v = 0.0;
      uint8_t raw[8];
      for (uint8_t& r : raw) r = byte();
      std::memcpy(&v, raw, sizeof v);
      return v;
    }
    return b / 4.0;
  }
  int64_t index() {
    const auto b = static_cast<int8_t>(byte());
    if (b != -128) return b;
    uint64_t v = 0;
    for (int k = 0; k < 8; ++k) v = v << 8 | byte();
    return static_cast<int64_t>(v);
  }

 private:
  const uint8_t* p_;
  size_t n_;
  size_t i_ = 0;
};

void check(const bsms::Mesh& mesh) {
  const bsms::BadCells bad = bsms::find_bad_cells(mesh);
  if (bad.count() < 0 || bad.count() > mesh.num_cells() || (bad.count() > 0) != (bad.first >= 0))
    __builtin_trap();
  (void)bad.describe();
}

void from_arrays(Reader& in) {
  const int dim = in.byte() % 5;   // 1..3 valid
  const int cols = in.byte() % 6;  // 2..4 valid (lines, triangles, tetrahedra)
  const int n = in.byte() % 33, c = in.byte() % 33;
  bsms::RowMatrixXd points(n, dim);
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < dim; ++a) points(i, a) = in.coordinate();
  bsms::RowMatrixXi64 cells(c, cols);
  for (int i = 0; i < c; ++i)
    for (int a = 0; a < cols; ++a) cells(i, a) = in.index();
  try {
    check(bsms::make_mesh(dim, std::move(points), std::move(cells)));
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
}

void from_gmsh(Reader& in) {
  // gmsh element types: 2-node line, 3-node triangle, 4-node tetrahedron (accepted), 6-node
  // triangle, 4-node quadrangle, 3-node line (refused). No points and no nodes on a model point:
  // libgmsh 4.8 corrupted its own heap with some of those (seen in gmsh::clear).
  static const int kTypes[] = {1, 2, 4, 9, 3, 8};
  static const int kTypeNodes[] = {2, 3, 4, 6, 4, 3};
  bsms::GmshSession session;
  try {
    for (int d = 1; d <= 3; ++d) gmsh::model::addDiscreteEntity(d, 1);
    const int n = in.byte() % 33;
    std::vector<std::size_t> tags;
    std::vector<double> coords;
    std::size_t tag = 0;
    for (int i = 0; i < n; ++i) {
      tag += 1 + in.byte() % 3;
      tags.push_back(tag);
      for (int a = 0; a < 3; ++a) coords.push_back(in.coordinate());
    }
    if (n > 0) gmsh::model::mesh::addNodes(1 + in.byte() % 3, 1, tags, coords);
    const int blocks = in.byte() % 3;
    for (int b = 0; b < blocks; ++b) {
      const int t = in.byte() % 6;
      const int count = in.byte() % 17;
      std::vector<std::size_t> nodes;
      for (int e = 0; e < count * kTypeNodes[t]; ++e) {
        // Only tags that exist: gmsh refuses others itself (and leaks the element it built,
        // which costs a full LeakSanitizer scan per input).
        nodes.push_back(n > 0 ? tags[in.byte() % n] : 1);
      }
      if (count > 0 && n > 0) gmsh::model::mesh::addElementsByType(1, kTypes[t], {}, nodes);
    }
  } catch (...) {
    session.reset();  // gmsh refused the arrays itself: not bsms' input layer
    return;
  }
  try {
    check(session.extract_mesh("fuzz.msh"));
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  session.reset();
}

// Coordinates in quarters (q / 4), as Reader::coordinate decodes them.
uint8_t q(int quarters) {
  return static_cast<uint8_t>(static_cast<int8_t>(quarters));
}

std::vector<std::vector<uint8_t>> seeds() {
  std::vector<std::vector<uint8_t>> out;
  // Arrays: a unit square as two triangles; the same with one triangle folded over the other;
  // a tetrahedron; a 1D line chain.
  out.push_back({1, 2, 3, 4, 2, 0, 0, q(4), 0, q(4), q(4), 0, q(4), 0, 1, 2, 0, 2, 3});
  out.push_back({1, 2, 3, 4, 2, 0, 0, q(4), 0, q(4), q(4), q(2), q(2), 0, 1, 2, 0, 1, 3});
  out.push_back({1, 3, 4, 4, 1, 0, 0, 0, q(4), 0, 0, 0, q(4), 0, 0, 0, q(4), 0, 1, 2, 3});
  out.push_back({1, 1, 2, 3, 2, 0, q(2), q(4), 0, 1, 1, 2});
  // gmsh model: 4 nodes (tags 1..4) on a surface, two triangles.
  out.push_back({0,    4, 0, 0, 0, 0, 0, q(4), 0, 0, 0, q(4), q(4), 0, 0, 0,
                 q(4), 0, 2, 1, 1, 2, 0, 1,    2, 0, 2, 3,    1,    2, 1});
  // The same nodes with a quadrangle (refused); a tetrahedron.
  out.push_back({0, 4, 0,    0, 0, 0, 0, q(4), 0, 0, 0, q(4), q(4), 0,
                 0, 0, q(4), 0, 2, 1, 4, 1,    0, 1, 2, 3,    0});
  out.push_back(
      {0, 4, 0, 0, 0, 0, 0, q(4), 0, 0, 0, 0, q(4), 0, 0, 0, 0, q(4), 3, 1, 2, 1, 0, 1, 2, 3, 0});
  return out;
}

}  // namespace

// gmsh leaks the element it built when addElementsByType refuses it: not bsms' leak.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libgmsh.so\n";
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bsms_fuzz::maybe_write_seeds(seeds);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Reader in(data, size);
  in.byte();  // the seeds' first byte: 1 arrays, 0 gmsh model
  if (BSMS_FUZZ_GMSH)
    from_gmsh(in);
  else
    from_arrays(in);
  return 0;
}
