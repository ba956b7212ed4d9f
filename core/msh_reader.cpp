#include "core/msh_reader.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "core/gmsh_elements.hpp"

namespace bsms {

namespace {

bool is_space(char c) {
  return c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == '\f' || c == '\v';
}

// A token of the input quoted for a message: at most 24 bytes up to blank space, bytes outside
// printable ASCII as \xNN.
std::string quote_token(const char* at, const char* end) {
  if (at >= end) return "end of file";
  std::string out = "'";
  int n = 0;
  for (const char* q = at; q < end && !is_space(*q) && n < 24; ++q, ++n) {
    const auto c = static_cast<unsigned char>(*q);
    if (c >= 32 && c < 127) {
      out += static_cast<char>(c);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    }
  }
  if (n == 24) out += "...";
  return out + "'";
}

// Element blocks as gmsh stores them: elements of one type on one entity, node tags in one list.
struct ElementBlock {
  int dim;
  int entity;
  int type;
  std::size_t list;  // index into MeshParts::tag_lists
};

class MshParser {
 public:
  MshParser(std::string_view bytes, const std::string& context)
      : begin_(bytes.data()),
        p_(bytes.data()),
        end_(bytes.data() + bytes.size()),
        context_(context) {}

  MeshParts parse();

 private:
  // --- messages
  [[noreturn]] void fail(const char* at, const std::string& what) const {
    std::string where;
    if (binary_) {
      where = "byte " + std::to_string(at - begin_);
    } else {
      where = "line " + std::to_string(1 + std::count(begin_, at, '\n'));
    }
    if (!section_.empty()) where += " in $" + section_;
    throw InputError(context_ + ": " + where + ": " + what);
  }
  [[noreturn]] void fail_expected(const char* at, const char* what) const {
    fail(at, std::string("expected ") + what + ", got " + quote_token(at, end_));
  }
  [[noreturn]] void not_handled(const std::string& what) const {
    throw MshNotHandled(context_ + ": " + what + " (left to gmsh)");
  }

  // --- ASCII
  void skip_space() {
    while (p_ < end_ && is_space(*p_)) ++p_;
  }
  bool at_token_end(const char* q) const { return q == end_ || is_space(*q); }
  // Where the next item starts, for messages (ASCII: after blank space).
  const char* here() {
    if (!binary_) skip_space();
    return p_;
  }

  template <class T>
  T read_integer(const char* what) {
    skip_space();
    const char* q = p_;
    if (q < end_ && *q == '+') ++q;  // scanf's %d accepts a sign
    T value{};
    const auto [ptr, ec] = std::from_chars(q, end_, value);
    if (ec != std::errc() || !at_token_end(ptr)) fail_expected(p_, what);
    p_ = ptr;
    return value;
  }

  int read_int(const char* what) { return read_integer<int>(what); }
  uint64_t read_count(const char* what) { return read_integer<uint64_t>(what); }

  double read_double(const char* what) {
    skip_space();
    const char* q = p_;
    if (q < end_ && *q == '+') ++q;
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(q, end_, value);
    if (ec == std::errc::result_out_of_range && at_token_end(ptr)) {
      // Overflow or underflow: what gmsh's fscanf (strtod) gives, +-inf or a denormal / zero.
      value = std::strtod(std::string(q, ptr).c_str(), nullptr);
    } else if (ec != std::errc() || !at_token_end(ptr)) {
      fail_expected(p_, what);
    }
    p_ = ptr;
    return value;
  }

  // Blank space up to and including the end of the current line (binary data follows it).
  void end_line() {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r')) ++p_;
    if (p_ < end_ && *p_ != '\n')
      fail(p_, "expected the end of the line, got " + quote_token(p_, end_));
    if (p_ < end_) ++p_;
  }

  // --- binary (little-endian, as gmsh writes on x86)
  void need_bytes(uint64_t count, uint64_t each, const char* what) const {
    const auto left = static_cast<uint64_t>(end_ - p_);
    if (each > 0 && count > left / each)
      fail(
          p_,
          "the file declares " + std::to_string(count) + " " + what + ", which need at least " +
              (count > std::numeric_limits<uint64_t>::max() / each ? std::string("2^64")
                                                                   : std::to_string(count * each)) +
              " bytes, but only " + std::to_string(left) + " are left (truncated file?)");
  }
  template <class T>
  T read_binary(const char* what) {
    if (static_cast<size_t>(end_ - p_) < sizeof(T))
      fail(p_, std::string("expected ") + what + " (" + std::to_string(sizeof(T)) + " bytes), " +
                   std::to_string(end_ - p_) + " bytes left");
    T value;
    std::memcpy(&value, p_, sizeof(T));
    p_ += sizeof(T);
    return value;
  }

  // Either encoding: counts are size_t, tags and types int.
  uint64_t count(const char* what) {
    return binary_ ? read_binary<uint64_t>(what) : read_count(what);
  }
  int integer(const char* what) { return binary_ ? read_binary<int32_t>(what) : read_int(what); }

  // --- sections
  bool next_section();
  void expect_end();
  void skip_section();
  void read_format();
  void read_physical_names();
  void read_entities();
  void read_nodes_v4();
  void read_elements_v4();
  void read_nodes_v2();
  void read_elements_v2();
  MeshParts finish();

  std::size_t add_block(int dim, int entity, int type);
  void set_physical_name(int dim, int tag, std::string name);

  const char* const begin_;
  const char* p_;
  const char* const end_;
  const std::string& context_;
  std::string section_;  // current section, without '$'
  bool binary_ = false;
  bool v4_ = false;

  MeshParts parts_;
  std::vector<ElementBlock> blocks_;
  std::map<std::tuple<int, int, int>, std::size_t> block_of_;  // 2.2: (dim, entity, type)
  std::set<std::pair<int, int>> entities_;                     // 4.1: (dim, tag) defined
  std::map<std::pair<int, int>, std::vector<int>> physicals_;  // (dim, entity) -> physical tags
  std::map<int, std::size_t> point_node_;  // 4.1: point entity -> first node on it
  std::map<std::pair<int, int>, std::string> names_;
  std::set<std::pair<int, std::string>> used_names_;  // (dim, name) given to a group
  int max_physical_[4] = {0, 0, 0, 0};
  bool have_nodes_ = false, have_elements_ = false, have_entities_ = false;
};

// Reads "$Name" and the rest of its line; false at the end of the input.
bool MshParser::next_section() {
  section_.clear();
  skip_space();
  if (p_ == end_) return false;
  if (*p_ != '$') fail_expected(p_, "a section header ($Name)");
  const char* name = p_ + 1;
  const char* e = name;
  while (e < end_ && !is_space(*e)) ++e;
  if (e == end_) fail(p_, "the file ends in the section header " + quote_token(p_, end_));
  section_.assign(name, e);
  p_ = e;
  end_line();
  return true;
}

// "$End<section>" after blank space.
void MshParser::expect_end() {
  skip_space();
  const std::string end = "$End" + section_;
  const auto left = static_cast<size_t>(end_ - p_);
  if (left < end.size() || std::memcmp(p_, end.data(), end.size()) != 0 ||
      !at_token_end(p_ + end.size()))
    fail_expected(p_, end.c_str());
  p_ += end.size();
  end_line();
}

// An unknown section: everything up to its "$End<section>" line.
void MshParser::skip_section() {
  const std::string end = "$End" + section_;
  const std::string_view rest(p_, static_cast<size_t>(end_ - p_));
  size_t at = 0;
  while (true) {
    at = rest.find(end, at);
    if (at == std::string_view::npos) fail(p_, "missing " + end);
    const bool line_start = at == 0 || rest[at - 1] == '\n';
    if (line_start && at_token_end(p_ + at + end.size())) break;
    ++at;
  }
  p_ += at + end.size();
  end_line();
}

void MshParser::read_format() {
  const char* at = here();
  skip_space();
  const char* version_at = p_;
  const double version = read_double("the format version (2.2 or 4.1)");
  const int file_type = read_int("the file type (0 ASCII, 1 binary)");
  const int data_size = read_int("the data size (8)");
  if (version == 4.1) {
    v4_ = true;
  } else if (version != 2.2) {
    not_handled("MSH version " + std::string(version_at, p_ - version_at) +
                " (the direct reader reads 2.2 and 4.1)");
  }
  if (file_type != 0 && file_type != 1) fail(at, "file type must be 0 (ASCII) or 1 (binary)");
  if (file_type == 1) {
    end_line();
    binary_ = true;
    const auto one = read_binary<int32_t>("the binary marker (int 1)");
    if (one != 1) {
      if (one == 0x01000000) not_handled("byte-swapped binary MSH");
      fail(p_ - 4, "binary marker is " + std::to_string(one) + ", expected 1");
    }
    if (data_size != 8)
      not_handled("binary MSH with " + std::to_string(data_size) + "-byte size_t");
  }
  expect_end();
}

// gmsh's GModel::setPhysicalName: a name already used in the dimension is ignored, the first
// name of a (dim, tag) stays, tag 0 takes the next free number.
void MshParser::set_physical_name(int dim, int tag, std::string name) {
  if (dim < 0 || dim > 3 || used_names_.count({dim, name})) return;
  if (tag == 0) tag = max_physical_[dim] + 1;
  if (names_.emplace(std::make_pair(dim, tag), name).second) used_names_.insert({dim, name});
}

void MshParser::read_physical_names() {
  // ASCII in binary files too.
  const uint64_t n = read_count("the number of physical names");
  for (uint64_t i = 0; i < n; ++i) {
    const int dim = read_int("the dimension of a physical name");
    const int tag = read_int("the tag of a physical name");
    // The rest of the line; the name is between the first quote and the next (at most 255
    // characters, as gmsh's ExtractDoubleQuotedString).
    const char* eol = p_;
    while (eol < end_ && *eol != '\n') ++eol;
    const char* quote = std::find(p_, eol, '"');
    std::string name;
    if (quote == eol) fail_expected(p_, "a quoted physical name");
    for (const char* c = quote + 1; c < eol && *c != '"' && *c != '\r' && name.size() < 255; ++c)
      name += *c;
    p_ = eol;
    if (!name.empty()) set_physical_name(dim, tag, std::move(name));
  }
  expect_end();
}

void MshParser::read_entities() {
  if (have_entities_) fail(p_, "second $Entities section");
  have_entities_ = true;
  uint64_t counts[4];
  for (uint64_t& c : counts) {
    c = count("the number of entities of a dimension (4 counts)");
    need_bytes(c, binary_ ? 36 : 10, "entities");
  }
  for (int dim = 0; dim < 4; ++dim) {
    for (uint64_t i = 0; i < counts[dim]; ++i) {
      const int tag = integer("an entity tag");
      for (int b = 0; b < (dim == 0 ? 3 : 6); ++b)
        binary_ ? (void)read_binary<double>("a bounding box coordinate")
                : (void)read_double("a bounding box coordinate");
      entities_.insert({dim, tag});
      auto& physicals = physicals_[{dim, tag}];
      const uint64_t num_physicals = count("the number of physical tags");
      need_bytes(num_physicals, binary_ ? 4 : 2, "physical tags");
      for (uint64_t k = 0; k < num_physicals; ++k) {
        const int physical = integer("a physical tag");
        physicals.push_back(physical);
        if (physical != std::numeric_limits<int>::min())
          max_physical_[dim] = std::max(max_physical_[dim], std::abs(physical));
      }
      if (dim > 0) {
        const uint64_t num_bounding = count("the number of bounding entities");
        need_bytes(num_bounding, binary_ ? 4 : 2, "bounding entities");
        for (uint64_t k = 0; k < num_bounding; ++k) integer("a bounding entity tag");
      }
    }
  }
  expect_end();
}

void MshParser::read_nodes_v4() {
  if (have_nodes_) fail(p_, "second $Nodes section");
  have_nodes_ = true;
  const uint64_t num_blocks = count("the number of node blocks");
  // The header's node count is a hint only: gmsh 4.8 itself writes it wrong when it saves a
  // subset of the nodes (physical groups without Mesh.SaveAll); the blocks are the truth.
  const uint64_t total = count("the number of nodes");
  count("the smallest node tag");
  count("the largest node tag");
  need_bytes(num_blocks, binary_ ? 20 : 8, "node blocks");
  auto& tags = parts_.node_tags;
  auto& coords = parts_.node_coords;
  const uint64_t fits = static_cast<uint64_t>(end_ - p_) / (binary_ ? 32 : 8);
  tags.reserve(std::min(total, fits));
  coords.reserve(3 * std::min(total, fits));
  for (uint64_t b = 0; b < num_blocks; ++b) {
    const char* at = here();
    const int dim = integer("the entity dimension of a node block");
    const int entity = integer("the entity tag of a node block");
    const int parametric = integer("the parametric flag of a node block (0 or 1)");
    const uint64_t n = count("the number of nodes in the block");
    if (dim < 0 || dim > 3)
      fail(at, "entity dimension " + std::to_string(dim) + ", expected 0 to 3");
    if (parametric != 0 && parametric != 1)
      fail(at, "parametric flag " + std::to_string(parametric) + ", expected 0 or 1");
    const int values = 3 + (parametric ? dim : 0);  // x y z, then u v w skipped
    need_bytes(n, binary_ ? 8 * (1 + values) : 2 * (1 + values), "nodes");
    entities_.insert({dim, entity});
    if (n == 0) continue;
    const size_t first = tags.size();
    tags.resize(first + n);
    coords.resize(3 * (first + n));
    if (binary_) {
      std::memcpy(tags.data() + first, p_, 8 * n);
      p_ += 8 * n;
      double* out = coords.data() + 3 * first;
      if (values == 3) {
        std::memcpy(out, p_, 24 * n);
        p_ += 24 * n;
      } else {
        for (uint64_t i = 0; i < n; ++i, p_ += 8 * values) std::memcpy(out + 3 * i, p_, 24);
      }
    } else {
      for (uint64_t i = 0; i < n; ++i) tags[first + i] = read_count("a node tag");
      double* out = coords.data() + 3 * first;
      for (uint64_t i = 0; i < n; ++i) {
        out[3 * i] = read_double("the x coordinate of a node");
        out[3 * i + 1] = read_double("the y coordinate of a node");
        out[3 * i + 2] = read_double("the z coordinate of a node");
        for (int v = 3; v < values; ++v) read_double("a parametric coordinate of a node");
      }
    }
    if (dim == 0) point_node_.emplace(entity, tags[first]);
  }
  expect_end();
}

std::size_t MshParser::add_block(int dim, int entity, int type) {
  blocks_.push_back({dim, entity, type, parts_.tag_lists.size()});
  parts_.tag_lists.emplace_back();
  return blocks_.size() - 1;
}

void MshParser::read_elements_v4() {
  if (have_elements_) fail(p_, "second $Elements section");
  have_elements_ = true;
  const uint64_t num_blocks = count("the number of element blocks");
  count("the number of elements");  // a hint only, like the node count
  count("the smallest element tag");
  count("the largest element tag");
  need_bytes(num_blocks, binary_ ? 20 : 8, "element blocks");
  for (uint64_t b = 0; b < num_blocks; ++b) {
    const char* at = here();
    const int dim = integer("the entity dimension of an element block");
    const int entity = integer("the entity tag of an element block");
    const int type = integer("the element type of an element block");
    const uint64_t n = count("the number of elements in the block");
    const GmshElementType* t = gmsh_element_type(type);
    if (!t) fail(at, "unknown gmsh element type " + std::to_string(type));
    if (t->num_nodes == 0) not_handled(std::string("variable-size elements (") + t->name + ")");
    if (t->dim != dim)
      fail(at, std::string(t->name) + " elements (dimension " + std::to_string(t->dim) +
                   ") in a block of entity dimension " + std::to_string(dim));
    if (!entities_.count({dim, entity}))
      fail(at, "element block on entity (" + std::to_string(dim) + ", " + std::to_string(entity) +
                   "), which neither $Entities nor $Nodes defines");
    const int k = t->num_nodes;
    need_bytes(n, binary_ ? 8 * (1 + k) : 2 * (1 + k), "elements");
    auto& list = parts_.tag_lists[blocks_[add_block(dim, entity, type)].list];
    list.resize(n * k);
    if (binary_) {
      for (uint64_t e = 0; e < n; ++e) {
        std::memcpy(list.data() + e * k, p_ + 8, 8 * k);
        p_ += 8 * (1 + k);
      }
    } else {
      std::size_t* out = list.data();
      for (uint64_t e = 0; e < n; ++e) {
        read_count("an element tag");
        for (int a = 0; a < k; ++a) *out++ = read_count("a node tag of an element");
      }
    }
  }
  expect_end();
}

void MshParser::read_nodes_v2() {
  if (have_nodes_) fail(p_, "second $Nodes section");
  have_nodes_ = true;
  const uint64_t n = read_count("the number of nodes");
  if (binary_) end_line();
  need_bytes(n, binary_ ? 28 : 8, "nodes");
  auto& tags = parts_.node_tags;
  auto& coords = parts_.node_coords;
  tags.resize(n);
  coords.resize(3 * n);
  if (binary_) {
    for (uint64_t i = 0; i < n; ++i) {
      int32_t tag;
      std::memcpy(&tag, p_, 4);
      if (tag < 0) fail(p_, "negative node tag " + std::to_string(tag));
      tags[i] = static_cast<std::size_t>(tag);
      std::memcpy(coords.data() + 3 * i, p_ + 4, 24);
      p_ += 28;
    }
  } else {
    for (uint64_t i = 0; i < n; ++i) {
      const int tag = read_int("a node tag");
      if (tag < 0) fail(p_, "negative node tag " + std::to_string(tag));
      tags[i] = static_cast<std::size_t>(tag);
      coords[3 * i] = read_double("the x coordinate of a node");
      coords[3 * i + 1] = read_double("the y coordinate of a node");
      coords[3 * i + 2] = read_double("the z coordinate of a node");
    }
  }
  expect_end();
}

void MshParser::read_elements_v2() {
  if (have_elements_) fail(p_, "second $Elements section");
  have_elements_ = true;
  const uint64_t total = read_count("the number of elements");
  if (binary_) end_line();
  need_bytes(total, 8, "elements");  // "1 15 0 1\n", or a tagless point in binary
  // Elements go to blocks by (dimension, elementary entity, type), in file order; the physical
  // tag puts the entity in a group.
  std::tuple<int, int, int> last_key{-1, 0, 0}, last_membership{-1, 0, 0};
  std::size_t last_block = 0;
  std::set<std::tuple<int, int, int>> physical_seen;  // (dim, entity, physical)
  auto store = [&](const GmshElementType* t, int physical, int entity, const int* node_tags,
                   const char* at) {
    for (int a = 0; a < t->num_nodes; ++a)
      if (node_tags[a] < 0) fail(at, "negative node tag " + std::to_string(node_tags[a]));
    if (entity < 0) return;  // gmsh skips elements of negative entities
    const std::tuple<int, int, int> key{t->dim, entity, t->type};
    if (key != last_key) {
      auto it = block_of_.find(key);
      if (it == block_of_.end())
        it = block_of_.emplace(key, add_block(t->dim, entity, t->type)).first;
      last_key = key;
      last_block = it->second;
    }
    auto& list = parts_.tag_lists[blocks_[last_block].list];
    for (int a = 0; a < t->num_nodes; ++a) list.push_back(static_cast<std::size_t>(node_tags[a]));
    if (physical != 0 && physical != std::numeric_limits<int>::min()) {
      const std::tuple<int, int, int> membership{t->dim, entity, std::abs(physical)};
      if (membership != last_membership && physical_seen.insert(membership).second)
        physicals_[{t->dim, entity}].push_back(std::abs(physical));
      last_membership = membership;
    }
  };
  auto element_type = [&](int type, const char* at) {
    const GmshElementType* t = gmsh_element_type(type);
    if (!t) fail(at, "unknown gmsh element type " + std::to_string(type));
    if (t->num_nodes == 0) not_handled(std::string("variable-size elements (") + t->name + ")");
    return t;
  };
  auto check_tags = [&](int num_tags, const char* at) {
    if (num_tags < 0) fail(at, "negative number of element tags");
    if (num_tags > 3) not_handled("MSH 2.2 elements with partition tags (a partitioned mesh)");
  };
  int nodes[1000];  // the largest gmsh element, Hexahedron 1000
  if (binary_) {
    uint64_t read = 0;
    while (read < total) {
      const char* at = here();
      const int type = read_binary<int32_t>("the element type of an element block");
      const int n = read_binary<int32_t>("the number of elements in the block");
      const int num_tags = read_binary<int32_t>("the number of tags per element");
      const GmshElementType* t = element_type(type, at);
      check_tags(num_tags, at);
      if (n < 0 || static_cast<uint64_t>(n) > total - read)
        fail(at, "an element block of " + std::to_string(n) + " elements where " +
                     std::to_string(total - read) + " remain of the declared " +
                     std::to_string(total));
      const int k = t->num_nodes;
      need_bytes(n, 4 * (1 + num_tags + k), "elements");
      for (int e = 0; e < n; ++e) {
        const char* element_at = p_;
        int32_t tags[3] = {0, 0, 0};
        std::memcpy(tags, p_ + 4, 4 * num_tags);
        std::memcpy(nodes, p_ + 4 * (1 + num_tags), 4 * k);
        p_ += 4 * (1 + num_tags + k);
        store(t, tags[0], tags[1], nodes, element_at);
      }
      read += n;
    }
  } else {
    for (uint64_t e = 0; e < total; ++e) {
      const char* at = here();
      read_int("an element number");
      const int type = read_int("an element type");
      const int num_tags = read_int("the number of element tags");
      const GmshElementType* t = element_type(type, at);
      check_tags(num_tags, at);
      int tags[3] = {0, 0, 0};
      for (int j = 0; j < num_tags; ++j) tags[j] = read_int("an element tag");
      for (int a = 0; a < t->num_nodes; ++a) nodes[a] = read_int("a node tag of an element");
      store(t, tags[0], tags[1], nodes, at);
    }
  }
  expect_end();
}

MeshParts MshParser::parse() {
  if (!next_section() || section_ != "MeshFormat") {
    section_.clear();
    fail(begin_, "expected $MeshFormat first");
  }
  read_format();
  while (next_section()) {
    if (section_ == "PhysicalNames") {
      read_physical_names();
    } else if (section_ == "Entities" && v4_) {
      read_entities();
    } else if (section_ == "PartitionedEntities") {
      not_handled("partitioned mesh ($PartitionedEntities)");
    } else if (section_ == "ParametricNodes") {
      not_handled("$ParametricNodes");
    } else if (section_ == "Nodes") {
      v4_ ? read_nodes_v4() : read_nodes_v2();
    } else if (section_ == "Elements") {
      v4_ ? read_elements_v4() : read_elements_v2();
    } else if (section_ == "MeshFormat") {
      fail(p_, "second $MeshFormat section");
    } else if (section_.compare(0, 3, "End") == 0) {
      const std::string end = "$" + section_;
      section_.clear();
      fail(p_, end + " without its section");
    } else {
      skip_section();
    }
  }
  section_.clear();
  return finish();
}

MeshParts MshParser::finish() {
  if (!have_elements_) throw InputError(context_ + ": no $Elements section (empty mesh)");
  // Cells: the blocks of the highest dimension with elements, by entity tag (gmsh's entity
  // order), blocks of one entity in file order.
  std::vector<std::size_t> top;
  for (std::size_t b = 0; b < blocks_.size(); ++b) {
    const ElementBlock& block = blocks_[b];
    if (block.dim < 1 || parts_.tag_lists[block.list].empty()) continue;
    if (block.dim > parts_.cell_dim) {
      parts_.cell_dim = block.dim;
      top.clear();
    }
    if (block.dim == parts_.cell_dim) top.push_back(b);
  }
  std::stable_sort(top.begin(), top.end(), [&](std::size_t a, std::size_t b) {
    return blocks_[a].entity < blocks_[b].entity;
  });
  for (std::size_t b : top) {
    parts_.cells.push_back(blocks_[b].list);
    const int type = blocks_[b].type;
    if (std::find(parts_.cell_types.begin(), parts_.cell_types.end(), type) ==
        parts_.cell_types.end())
      parts_.cell_types.push_back(type);
  }
  std::sort(parts_.cell_types.begin(), parts_.cell_types.end());

  // Physical groups: (dim, tag) -> entities -> their element blocks.
  std::map<std::pair<int, int>, std::vector<std::size_t>> blocks_of;  // (dim, entity) -> blocks
  for (std::size_t b = 0; b < blocks_.size(); ++b)
    blocks_of[{blocks_[b].dim, blocks_[b].entity}].push_back(b);
  std::map<std::pair<int, int>, std::set<int>> groups;
  for (const auto& [entity, physicals] : physicals_)
    for (int physical : physicals)
      if (physical != std::numeric_limits<int>::min())
        groups[{entity.first, std::abs(physical)}].insert(entity.second);
  for (const auto& [key, entities] : groups) {
    MeshParts::Group group;
    group.dim = key.first;
    group.tag = key.second;
    const auto name = names_.find(key);
    if (name != names_.end()) group.name = name->second;
    if (group.dim > 0) {
      for (int entity : entities) {
        const auto it = blocks_of.find({group.dim, entity});
        if (it == blocks_of.end()) continue;
        for (std::size_t b : it->second) group.lists.push_back(blocks_[b].list);
      }
    } else {
      // A point's node: the first node classified on it (4.1), else the lowest-tag node of its
      // point elements (what gmsh classifies on the point when reading 2.2).
      std::vector<std::size_t> nodes;
      for (int entity : entities) {
        const auto it = point_node_.find(entity);
        if (it != point_node_.end()) {
          nodes.push_back(it->second);
          continue;
        }
        std::size_t lowest = std::numeric_limits<std::size_t>::max();
        const auto blocks = blocks_of.find({0, entity});
        if (blocks != blocks_of.end())
          for (std::size_t b : blocks->second)
            for (std::size_t tag : parts_.tag_lists[blocks_[b].list])
              lowest = std::min(lowest, tag);
        if (lowest != std::numeric_limits<std::size_t>::max()) nodes.push_back(lowest);
      }
      group.lists.push_back(parts_.tag_lists.size());
      parts_.tag_lists.push_back(std::move(nodes));
    }
    parts_.groups.push_back(std::move(group));
  }
  return std::move(parts_);
}

// The file's bytes: mapped read-only (read into memory where mapping fails).
class FileBytes {
 public:
  explicit FileBytes(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw InputError(path + ": cannot open mesh file (" + std::strerror(errno) + ")");
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
      void* map = ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ,
                         MAP_PRIVATE | MAP_POPULATE, fd, 0);
      if (map != MAP_FAILED) {
        data_ = static_cast<const char*>(map);
        size_ = static_cast<size_t>(st.st_size);
        mapped_ = true;
      }
    }
    if (!mapped_) {
      char buffer[1 << 16];
      ssize_t got;
      while ((got = ::read(fd, buffer, sizeof buffer)) > 0) copy_.append(buffer, got);
      const int error = errno;
      if (got < 0) {
        ::close(fd);
        throw InputError(path + ": cannot read mesh file (" + std::strerror(error) + ")");
      }
      data_ = copy_.data();
      size_ = copy_.size();
    }
    ::close(fd);
  }
  ~FileBytes() {
    if (mapped_) ::munmap(const_cast<char*>(data_), size_);
  }
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;
  std::string_view bytes() const { return {data_, size_}; }

 private:
  const char* data_ = nullptr;
  size_t size_ = 0;
  bool mapped_ = false;
  std::string copy_;
};

}  // namespace

bool is_direct_msh(std::string_view head) {
  size_t i = 0;
  while (i < head.size() && is_space(head[i])) ++i;
  const std::string_view tag = "$MeshFormat";
  if (head.compare(i, tag.size(), tag) != 0) return false;
  i += tag.size();
  if (i >= head.size() || !is_space(head[i])) return false;
  while (i < head.size() && is_space(head[i])) ++i;
  double version = 0.0;
  const auto [ptr, ec] = std::from_chars(head.data() + i, head.data() + head.size(), version);
  if (ec != std::errc() || (ptr != head.data() + head.size() && !is_space(*ptr))) return false;
  return version == 2.2 || version == 4.1;
}

MeshParts parse_msh(std::string_view bytes, const std::string& context) {
  return MshParser(bytes, context).parse();
}

Mesh read_msh_bytes(std::string_view bytes, const std::string& context) {
  return assemble_mesh(parse_msh(bytes, context), context);
}

Mesh read_msh(const std::string& path) {
  MeshParts parts;
  {
    const FileBytes file(path);
    parts = parse_msh(file.bytes(), path);
  }
  return assemble_mesh(std::move(parts), path);
}

}  // namespace bsms
