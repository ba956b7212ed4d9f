#include "core/gmsh_result.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <vector>

namespace bsms {

namespace {

constexpr char kMagic[8] = {'B', 'S', 'M', 'S', 'G', 'M', 'W', '1'};
constexpr char kEnd[8] = {'B', 'S', 'M', 'S', 'E', 'N', 'D', '1'};

class Writer {
 public:
  explicit Writer(int fd) : fd_(fd) {}
  bool bytes(const void* data, std::size_t size) {
    const char* p = static_cast<const char*>(data);
    while (size > 0 && ok_) {
      const ssize_t n = ::write(fd_, p, size);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        ok_ = false;
        break;
      }
      p += n;
      size -= static_cast<std::size_t>(n);
    }
    return ok_;
  }
  template <typename T>
  bool value(T v) {
    return bytes(&v, sizeof v);
  }
  bool ok() const { return ok_; }

 private:
  int fd_;
  bool ok_ = true;
};

class Reader {
 public:
  explicit Reader(std::string_view bytes) : b_(bytes) {}
  const char* take(uint64_t size, const char* what) {
    if (size > b_.size() - at_)
      throw std::runtime_error(std::string("gmsh worker result cut short in ") + what);
    const char* p = b_.data() + at_;
    at_ += static_cast<std::size_t>(size);
    return p;
  }
  template <typename T>
  T value(const char* what) {
    T v;
    std::memcpy(&v, take(sizeof v, what), sizeof v);
    return v;
  }
  // Bytes of `count` elements of `size` bytes, refused before anything is allocated.
  uint64_t span(uint64_t count, uint64_t size, const char* what) const {
    if (count > (b_.size() - at_) / size)
      throw std::runtime_error(std::string("gmsh worker result: ") + what +
                               " larger than the result");
    return count * size;
  }
  bool done() const { return at_ == b_.size(); }

 private:
  std::string_view b_;
  std::size_t at_ = 0;
};

}  // namespace

bool write_gmsh_result(int fd, const GmshResult& result) {
  Writer w(fd);
  w.bytes(kMagic, sizeof kMagic);
  w.value(static_cast<uint32_t>(result.status));
  w.value(uint32_t{0});
  if (result.status != GmshResult::Status::Mesh) {
    w.value(static_cast<uint64_t>(result.message.size()));
    w.bytes(result.message.data(), result.message.size());
  } else {
    const Mesh& m = result.mesh;
    w.value(static_cast<int32_t>(m.dim));
    w.value(static_cast<int32_t>(m.cell_dim));
    w.value(static_cast<int64_t>(m.num_nodes()));
    w.value(static_cast<int64_t>(m.num_cells()));
    w.value(static_cast<uint64_t>(m.node_groups.size()));
    w.bytes(m.points.data(), static_cast<std::size_t>(m.points.size()) * sizeof(double));
    w.bytes(m.cells.data(), static_cast<std::size_t>(m.cells.size()) * sizeof(int64_t));
    w.bytes(m.node_tags.data(), m.node_tags.size() * sizeof(int64_t));
    for (const auto& [name, nodes] : m.node_groups) {
      w.value(static_cast<uint64_t>(name.size()));
      w.bytes(name.data(), name.size());
      w.value(static_cast<uint64_t>(nodes.size()));
      w.bytes(nodes.data(), nodes.size() * sizeof(int64_t));
    }
  }
  w.bytes(kEnd, sizeof kEnd);
  return w.ok();
}

GmshResult parse_gmsh_result(std::string_view bytes) {
  Reader r(bytes);
  if (std::memcmp(r.take(sizeof kMagic, "its header"), kMagic, sizeof kMagic) != 0)
    throw std::runtime_error("gmsh worker result has no BSMSGMW1 header");
  GmshResult result;
  const auto status = r.value<uint32_t>("its header");
  r.value<uint32_t>("its header");
  if (status > static_cast<uint32_t>(GmshResult::Status::Failure))
    throw std::runtime_error("gmsh worker result has an unknown status " + std::to_string(status));
  result.status = static_cast<GmshResult::Status>(status);
  if (result.status != GmshResult::Status::Mesh) {
    const auto length = r.value<uint64_t>("its message");
    const char* text = r.take(r.span(length, 1, "the message"), "its message");
    result.message.assign(text, static_cast<std::size_t>(length));
  } else {
    Mesh& m = result.mesh;
    m.dim = r.value<int32_t>("the mesh header");
    m.cell_dim = r.value<int32_t>("the mesh header");
    const auto n = r.value<int64_t>("the mesh header");
    const auto c = r.value<int64_t>("the mesh header");
    const auto groups = r.value<uint64_t>("the mesh header");
    if (m.dim < 1 || m.dim > 3 || m.cell_dim < 1 || m.cell_dim > 3 || n < 0 || c < 0)
      throw std::runtime_error("gmsh worker result has an impossible mesh header");
    const auto un = static_cast<uint64_t>(n), uc = static_cast<uint64_t>(c);
    const uint64_t k = static_cast<uint64_t>(m.cell_dim) + 1;
    const uint64_t point_bytes =
        r.span(un, sizeof(double) * static_cast<uint64_t>(m.dim), "the points");
    m.points.resize(n, m.dim);
    std::memcpy(m.points.data(), r.take(point_bytes, "the points"), point_bytes);
    const uint64_t cell_bytes = r.span(uc, sizeof(int64_t) * k, "the cells");
    m.cells.resize(c, static_cast<Eigen::Index>(k));
    std::memcpy(m.cells.data(), r.take(cell_bytes, "the cells"), cell_bytes);
    const uint64_t tag_bytes = r.span(un, sizeof(int64_t), "the node tags");
    m.node_tags.resize(un);
    std::memcpy(m.node_tags.data(), r.take(tag_bytes, "the node tags"), tag_bytes);
    for (uint64_t g = 0; g < groups; ++g) {
      const auto name_length = r.value<uint64_t>("a group");
      const char* name = r.take(r.span(name_length, 1, "a group name"), "a group");
      const auto count = r.value<uint64_t>("a group");
      std::vector<int64_t>& nodes =
          m.node_groups[std::string(name, static_cast<std::size_t>(name_length))];
      if (!nodes.empty()) throw std::runtime_error("gmsh worker result repeats a group");
      const uint64_t node_bytes = r.span(count, sizeof(int64_t), "a group");
      nodes.resize(count);
      std::memcpy(nodes.data(), r.take(node_bytes, "a group"), node_bytes);
      for (int64_t v : nodes)
        if (v < 0 || v >= n)
          throw std::runtime_error("gmsh worker result has a group node out of range");
    }
  }
  if (std::memcmp(r.take(sizeof kEnd, "its end"), kEnd, sizeof kEnd) != 0 || !r.done())
    throw std::runtime_error("gmsh worker result does not end where it should");
  return result;
}

}  // namespace bsms
