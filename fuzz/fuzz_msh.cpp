// libFuzzer target for the direct MSH reader: the input is an MSH file image, parsed
// by read_msh_bytes (parse_msh + assemble_mesh) as read_mesh would parse a file. InputError
// (MshNotHandled included) is the only allowed outcome of bad bytes; a mesh that is accepted must
// have strictly ascending node tags and groups of valid, sorted node indices. Seeds (MSH 2.2 and
// 4.1, ASCII and binary, with physical groups): BSMS_FUZZ_WRITE_SEEDS=DIR fuzz_msh.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"
#include "core/mesh.hpp"
#include "core/msh_reader.hpp"
#include "seeds.hpp"

namespace {

void check(const bsms::Mesh& mesh) {
  for (size_t i = 1; i < mesh.node_tags.size(); ++i)
    if (mesh.node_tags[i - 1] >= mesh.node_tags[i]) __builtin_trap();
  for (const auto& [name, nodes] : mesh.node_groups)
    for (size_t i = 0; i < nodes.size(); ++i)
      if (nodes[i] < 0 || nodes[i] >= mesh.num_nodes() || (i > 0 && nodes[i - 1] >= nodes[i]))
        __builtin_trap();
}

// Little-endian binary pieces of a seed.
class Bytes {
 public:
  Bytes& text(std::string_view s) {
    out_.insert(out_.end(), s.begin(), s.end());
    return *this;
  }
  template <class T>
  Bytes& put(T value) {
    uint8_t raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    out_.insert(out_.end(), raw, raw + sizeof(T));
    return *this;
  }
  std::vector<uint8_t> take() { return std::move(out_); }

 private:
  std::vector<uint8_t> out_;
};

std::vector<uint8_t> bytes_of(std::string_view s) {
  return {s.begin(), s.end()};
}

std::vector<std::vector<uint8_t>> seeds() {
  std::vector<std::vector<uint8_t>> out;
  // MSH 2.2 ASCII: two triangles on entity 4 (group 3), a line (group "edge"), a point, an
  // unused node, sparse tags.
  out.push_back(bytes_of(R"($MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
2
1 9 "edge"
0 8 "corner"
$EndPhysicalNames
$Nodes
5
900 1 1 0
12 0 0 0
70 1 0 0
5 0 1 0
31 7 7 7
$EndNodes
$Elements
4
10 2 2 3 4 12 70 900
11 2 2 0 4 12 900 5
12 1 2 9 2 12 70
13 15 2 8 1 12
$EndElements
)"));
  // MSH 4.1 ASCII: entities with physical tags, a parametric node block, a tetrahedron.
  out.push_back(bytes_of(R"($MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
3 1 "solid"
2 2 "face"
$EndPhysicalNames
$Entities
0 0 1 1
2 0 0 0 1 1 0 1 2 0
1 0 0 0 1 1 1 1 1 1 2
$EndEntities
$Nodes
2 4 1 4
2 2 1 3
1
2
3
0 0 0 0 0
1 0 0 1 0
0 1 0 0 1
3 1 0 1
4
0 0 1
$EndNodes
$Elements
2 2 1 2
2 2 2 1
1 1 2 3
3 1 4 1
2 1 2 3 4
$EndElements
$Periodic
0
$EndPeriodic
)"));
  // MSH 4.1 binary: one surface, two triangles, a physical group.
  {
    Bytes b;
    b.text("$MeshFormat\n4.1 1 8\n").put<int32_t>(1).text("\n$EndMeshFormat\n");
    b.text("$Entities\n").put<uint64_t>(0).put<uint64_t>(0).put<uint64_t>(1).put<uint64_t>(0);
    b.put<int32_t>(1);
    for (double v : {0.0, 0.0, 0.0, 1.0, 1.0, 0.0}) b.put(v);
    b.put<uint64_t>(1).put<int32_t>(7).put<uint64_t>(0).text("\n$EndEntities\n");
    b.text("$Nodes\n").put<uint64_t>(1).put<uint64_t>(4).put<uint64_t>(1).put<uint64_t>(4);
    b.put<int32_t>(2).put<int32_t>(1).put<int32_t>(0).put<uint64_t>(4);
    for (uint64_t t = 1; t <= 4; ++t) b.put(t);
    for (double v : {0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0}) b.put(v);
    b.text("\n$EndNodes\n$Elements\n");
    b.put<uint64_t>(1).put<uint64_t>(2).put<uint64_t>(1).put<uint64_t>(2);
    b.put<int32_t>(2).put<int32_t>(1).put<int32_t>(2).put<uint64_t>(2);
    for (uint64_t v : {1, 1, 2, 3, 2, 1, 3, 4}) b.put(v);
    b.text("\n$EndElements\n");
    out.push_back(b.take());
  }
  // MSH 2.2 binary: the same square, one block of two triangles with two tags each.
  {
    Bytes b;
    b.text("$MeshFormat\n2.2 1 8\n").put<int32_t>(1).text("\n$EndMeshFormat\n$Nodes\n4\n");
    const double xy[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (int i = 0; i < 4; ++i) b.put<int32_t>(i + 1).put(xy[i][0]).put(xy[i][1]).put(0.0);
    b.text("\n$EndNodes\n$Elements\n2\n").put<int32_t>(2).put<int32_t>(2).put<int32_t>(2);
    for (int32_t v : {1, 5, 1, 1, 2, 3, 2, 5, 1, 1, 3, 4}) b.put(v);
    b.text("\n$EndElements\n");
    out.push_back(b.take());
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bsms_fuzz::maybe_write_seeds(seeds);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    check(bsms::read_msh_bytes(std::string_view(reinterpret_cast<const char*>(data), size),
                               "fuzz.msh"));
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  return 0;
}
