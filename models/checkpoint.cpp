#include "models/checkpoint.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <unordered_map>
#include <utility>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"

namespace bsms {

namespace {

const char* const kModel = "/model";
const char* const kOptimizer = "/optimizer";
const char* const kState = "/optimizer/state";
const char* const kEma = "/ema";
const char* const kMoments[] = {"exp_avg", "exp_avg_sq", "max_exp_avg_sq"};

// FNV-1a over 64-bit words (then the tail bytes): a digest of each tensor's bytes, stored next to
// it, so that a damaged value (which the HDF5 metadata checksums do not cover) is found.
uint64_t digest_bytes(const void* data, size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  uint64_t h = 0xcbf29ce484222325ull;
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    uint64_t word;
    std::memcpy(&word, p + i, 8);
    h = (h ^ word) * 0x100000001b3ull;
  }
  for (; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

H5Dtype h5_dtype(torch::ScalarType t) {
  switch (t) {
    case torch::kFloat:
      return H5Dtype::kFloat32;
    case torch::kDouble:
      return H5Dtype::kFloat64;
    case torch::kLong:
      return H5Dtype::kInt64;
    case torch::kInt:
      return H5Dtype::kInt32;
    case torch::kByte:
      return H5Dtype::kUInt8;
    default:
      return H5Dtype::kOther;
  }
}

torch::ScalarType torch_dtype(H5Dtype t) {
  switch (t) {
    case H5Dtype::kFloat32:
      return torch::kFloat;
    case H5Dtype::kFloat64:
      return torch::kDouble;
    case H5Dtype::kInt64:
      return torch::kLong;
    case H5Dtype::kInt32:
      return torch::kInt;
    case H5Dtype::kUInt8:
      return torch::kByte;
    case H5Dtype::kOther:
      break;
  }
  return torch::kFloat;  // not reached: kOther is refused first
}

std::string shape_text(c10::IntArrayRef sizes, torch::ScalarType dtype) {
  std::string out = "[";
  for (size_t i = 0; i < sizes.size(); ++i) out += (i ? ", " : "") + std::to_string(sizes[i]);
  return out + "] " + h5_dtype_name(h5_dtype(dtype));
}

// Longer user strings are cut in messages.
std::string clip(const std::string& s, size_t most = 60) {
  std::string out = s.size() > most ? s.substr(0, most) + "..." : s;
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 32) c = '?';
  return out;
}

class Writer {
 public:
  explicit Writer(H5File& f) : f_(f) {}
  void tensor(const std::string& object, const torch::Tensor& value) {
    const torch::Tensor t = value.detach().to(torch::kCPU).contiguous();
    Shape shape(t.sizes().begin(), t.sizes().end());
    switch (t.scalar_type()) {
      case torch::kFloat:
        f_.write(object, t.data_ptr<float>(), shape);
        break;
      case torch::kDouble:
        f_.write(object, t.data_ptr<double>(), shape);
        break;
      case torch::kLong:
        f_.write(object, t.data_ptr<int64_t>(), shape);
        break;
      case torch::kInt:
        f_.write(object, t.data_ptr<int32_t>(), shape);
        break;
      case torch::kByte:
        f_.write(object, t.data_ptr<uint8_t>(), shape);
        break;
      default:
        throw IoError(f_.path() + ": " + object + " has dtype " +
                      std::string(c10::toString(t.scalar_type())) +
                      ", which checkpoints do not store");
    }
    const uint64_t d = digest_bytes(t.data_ptr(), t.nbytes());
    int64_t stored;
    std::memcpy(&stored, &d, sizeof d);
    f_.set_attr(object, "digest", stored);
  }

 private:
  H5File& f_;
};

// The module's parameters then buffers, by dotted name.
std::vector<std::pair<std::string, torch::Tensor>> module_entries(const torch::nn::Module& m) {
  std::vector<std::pair<std::string, torch::Tensor>> out;
  for (const auto& p : m.named_parameters(/*recurse=*/true)) out.emplace_back(p.key(), p.value());
  for (const auto& b : m.named_buffers(/*recurse=*/true)) out.emplace_back(b.key(), b.value());
  return out;
}

std::string impl_key(const torch::Tensor& t) {
  return c10::guts::to_string(t.unsafeGetTensorImpl());
}

// The dotted name of each parameter of `optimizer`, in param_groups order.
std::vector<std::string> optimizer_parameter_names(const torch::nn::Module& module,
                                                   const torch::optim::Adam& optimizer) {
  std::unordered_map<const void*, std::string> names;
  for (const auto& p : module.named_parameters(/*recurse=*/true))
    names.emplace(p.value().unsafeGetTensorImpl(), p.key());
  std::vector<std::string> out;
  for (const auto& group : optimizer.param_groups())
    for (const auto& p : group.params()) {
      const auto it = names.find(p.unsafeGetTensorImpl());
      if (it == names.end())
        throw std::invalid_argument(
            "checkpoint: the optimizer holds a tensor that is not a "
            "parameter of the module");
      out.push_back(it->second);
    }
  return out;
}

// ---- reading -------------------------------------------------------------------------------

class Reader {
 public:
  Reader(const std::string& name, const std::string& bytes) : name_(name), size_(bytes.size()) {
    check_superblock(bytes);
    file_.emplace(H5File::open_image(name, bytes.data(), bytes.size()));
  }
  const H5File& file() const { return *file_; }

  [[noreturn]] void fail(const std::string& entry, const std::string& what) const {
    throw InputError(name_ + ": entry '" + clip(entry, 120) + "' " + what);
  }
  [[noreturn]] void fail(const std::string& what) const { throw InputError(name_ + ": " + what); }

  // Members of a group reached through hard links, each a hard link itself.
  std::vector<std::string> members(const std::string& group) const {
    if (!file_->is_hard_link(group) || !file_->is_group(group))
      fail(entry_of(group), "is missing or not a group");
    std::vector<std::string> out = file_->list(group);
    for (const auto& m : out)
      if (!file_->is_hard_link(group + "/" + m))
        fail(entry_of(group + "/" + m), "is a soft or external link (not followed)");
    return out;
  }

  int64_t int_attr(const std::string& object, const char* attr) const {
    return file_->attr_int(object, attr);
  }
  double double_attr(const std::string& object, const char* attr) const {
    return file_->attr_double(object, attr);
  }

  // A dataset as a tensor after every check that needs no model: known type, storage of exactly
  // its elements inside the file, its digest, finite values.
  torch::Tensor tensor(const std::string& object) const {
    const std::string entry = entry_of(object);
    const H5DatasetInfo info = file_->dataset_info(object);
    if (info.dtype == H5Dtype::kOther)
      fail(entry,
           "has an element type checkpoints do not use (float32, float64, int64, int32, "
           "uint8)");
    if (info.shape.size() > 8) fail(entry, "has rank " + std::to_string(info.shape.size()));
    uint64_t bytes = info.element_size;
    for (hsize_t d : info.shape)
      if (__builtin_mul_overflow(bytes, static_cast<uint64_t>(d), &bytes) ||
          d > static_cast<hsize_t>(INT64_MAX))
        fail(entry, "has an impossible shape");
    if (bytes > size_)
      fail(entry, "needs " + std::to_string(bytes) + " bytes, more than the file's " +
                      std::to_string(size_));
    if (bytes > 0) {
      if (!info.contiguous) fail(entry, "is not stored contiguously");
      if (info.storage_bytes != bytes)
        fail(entry, "stores " + std::to_string(info.storage_bytes) + " bytes for " +
                        std::to_string(info.elements()) + " elements (" + std::to_string(bytes) +
                        " expected)");
      if (info.address == HADDR_UNDEF || info.address > size_ || size_ - info.address < bytes)
        fail(entry, "has its values outside the file");
    }
    if (!file_->has_attr(object, "digest")) fail(entry, "has no digest attribute");
    const int64_t stored = file_->attr_int(object, "digest");
    std::vector<int64_t> sizes(info.shape.begin(), info.shape.end());
    torch::Tensor t = torch::empty(sizes, torch::TensorOptions().dtype(torch_dtype(info.dtype)));
    if (t.numel() > 0) read_into(object, t);
    const uint64_t d = digest_bytes(t.data_ptr(), t.nbytes());
    int64_t computed;
    std::memcpy(&computed, &d, sizeof d);
    if (computed != stored) fail(entry, "does not match its digest (the values are damaged)");
    if (t.is_floating_point() && !torch::isfinite(t).all().item<bool>())
      fail(entry, "has a non-finite value (NaN or inf)");
    return t;
  }

  static std::string entry_of(const std::string& object) {
    return object.size() > 1 && object[0] == '/' ? object.substr(1) : object;
  }

 private:
  // Before libhdf5 parses anything: the signature at offset 0 (no user block), a superblock of
  // version 2 or 3 (checksummed; the only kind bsms writes) with 8-byte addresses and lengths,
  // and an end-of-file address inside the bytes (a truncated file is named as such).
  void check_superblock(const std::string& b) const {
    static const char kSignature[] = "\x89HDF\r\n\x1a\n";
    if (b.size() < 48 || std::memcmp(b.data(), kSignature, 8) != 0)
      fail("not an HDF5 file (" + std::to_string(b.size()) +
           " bytes; a checkpoint starts with "
           "the HDF5 signature)");
    const int version = static_cast<unsigned char>(b[8]);
    if (version != 2 && version != 3)
      fail("HDF5 superblock version " + std::to_string(version) +
           ", not a bsms checkpoint (written with version 2 or 3: checksummed metadata)");
    if (b[9] != 8 || b[10] != 8) fail("HDF5 superblock with unusual address sizes (damaged?)");
    uint64_t base, eof;
    std::memcpy(&base, b.data() + 12, 8);
    std::memcpy(&eof, b.data() + 28, 8);
    if (base != 0) fail("HDF5 file with a user block (not a bsms checkpoint)");
    if (eof > b.size())
      fail("truncated: its HDF5 superblock says " + std::to_string(eof) + " bytes, the file has " +
           std::to_string(b.size()));
  }

  template <class T>
  void copy_values(const std::string& object, torch::Tensor& t) const {
    const std::vector<T> values = file_->read<T>(object);
    if (values.size() != static_cast<size_t>(t.numel()))
      fail(entry_of(object), "changed size while read");
    std::memcpy(t.data_ptr(), values.data(), values.size() * sizeof(T));
  }
  void read_into(const std::string& object, torch::Tensor& t) const {
    switch (t.scalar_type()) {
      case torch::kFloat:
        return copy_values<float>(object, t);
      case torch::kDouble:
        return copy_values<double>(object, t);
      case torch::kLong:
        return copy_values<int64_t>(object, t);
      case torch::kInt:
        return copy_values<int32_t>(object, t);
      default:
        return copy_values<uint8_t>(object, t);
    }
  }

  std::string name_;
  uint64_t size_;
  std::optional<H5File> file_;
};

bool is_index(const std::string& s) {
  return !s.empty() && s.size() <= 9 && std::all_of(s.begin(), s.end(), ::isdigit) &&
         (s == "0" || s[0] != '0');
}

// The root's format, version and kind attributes checked; returns the kind ("training" or
// "module").
std::string read_kind(const Reader& r) {
  const H5File& f = r.file();
  const std::string format = f.has_attr("/", "format") ? f.attr_string("/", "format") : "";
  if (format != kCheckpointFormat)
    r.fail("not a bsms checkpoint (format attribute '" + clip(format) + "', expected '" +
           kCheckpointFormat + "')");
  const int64_t version = r.int_attr("/", "version");
  if (version != kCheckpointVersion)
    r.fail("checkpoint format version " + std::to_string(version) + "; this bsms reads version " +
           std::to_string(kCheckpointVersion));
  const std::string kind = r.file().attr_string("/", "kind");
  if (kind != "training" && kind != "module")
    r.fail("kind '" + clip(kind) + "' (expected 'training' or 'module')");
  return kind;
}

// The members of `group`, checked against its `count` attribute: the entry count, stored apart
// from the group's index, names a lost or added entry even without a model to compare with
// (bsms info).
std::vector<std::string> counted_members(const Reader& r, const std::string& group) {
  const std::vector<std::string> entries = r.members(group);
  const int64_t count = r.int_attr(group, "count");
  if (count != static_cast<int64_t>(entries.size()))
    r.fail(Reader::entry_of(group), "has " + std::to_string(entries.size()) +
                                        " entries, its count says " + std::to_string(count) +
                                        " (an entry lost or added)");
  return entries;
}

// The model's entries, in the group's order.
void read_model(const Reader& r, CheckpointContents& c) {
  for (const auto& m : counted_members(r, kModel))
    c.model.push_back({m, r.tensor(std::string(kModel) + "/" + m)});
}

void read_training_state(const Reader& r, TrainingState& s) {
  s.step = r.int_attr("/", "step");
  if (s.step < 0) r.fail("step " + std::to_string(s.step) + " (expected >= 0)");
  s.wall_s = r.double_attr("/", "wall_s");
  if (!std::isfinite(s.wall_s) || s.wall_s < 0)
    r.fail("wall_s " + std::to_string(s.wall_s) + " (expected a finite time >= 0)");
  s.loss = r.double_attr("/", "loss");
  s.valid_loss = r.double_attr("/", "valid_loss");
  s.valid_zero_prediction = r.double_attr("/", "valid_zero_prediction");
}

// One parameter group's settings, checked; `total`: the parameters of the groups before it.
AdamGroup read_group(const Reader& r, const std::string& group, int64_t total) {
  if (!r.file().is_hard_link(group) || !r.file().is_group(group))
    r.fail(Reader::entry_of(group), "is missing or not a group");
  AdamGroup o;
  o.lr = r.double_attr(group, "lr");
  o.beta1 = r.double_attr(group, "beta1");
  o.beta2 = r.double_attr(group, "beta2");
  o.eps = r.double_attr(group, "eps");
  o.weight_decay = r.double_attr(group, "weight_decay");
  const int64_t amsgrad = r.int_attr(group, "amsgrad");
  o.size = r.int_attr(group, "size");
  const std::string entry = Reader::entry_of(group);
  if (!std::isfinite(o.lr) || o.lr < 0) r.fail(entry, "has lr " + std::to_string(o.lr));
  if (!(o.beta1 >= 0 && o.beta1 < 1) || !(o.beta2 >= 0 && o.beta2 < 1))
    r.fail(entry, "has betas outside [0, 1)");
  if (!std::isfinite(o.eps) || o.eps <= 0) r.fail(entry, "has eps " + std::to_string(o.eps));
  if (!std::isfinite(o.weight_decay) || o.weight_decay < 0)
    r.fail(entry, "has weight_decay " + std::to_string(o.weight_decay));
  if (amsgrad != 0 && amsgrad != 1) r.fail(entry, "has amsgrad " + std::to_string(amsgrad));
  if (o.size < 0 || o.size > 100000000 || total + o.size > 100000000)
    r.fail(entry, "has size " + std::to_string(o.size));
  o.amsgrad = amsgrad == 1;
  return o;
}

// The optimizer's parameter groups into c.groups; returns whether each parameter (by index) uses
// amsgrad; `total` receives the parameter count.
std::vector<bool> read_groups(const Reader& r, CheckpointContents& c, int64_t& total) {
  const int64_t groups = r.int_attr(kOptimizer, "groups");
  if (groups < 1 || groups > 1000)
    r.fail("optimizer", "has " + std::to_string(groups) + " parameter groups");
  std::set<std::string> expected_members = {"state"};
  total = 0;
  std::vector<bool> amsgrad_of;  // per parameter index
  for (int64_t g = 0; g < groups; ++g) {
    const std::string group = std::string(kOptimizer) + "/group_" + std::to_string(g);
    expected_members.insert("group_" + std::to_string(g));
    const AdamGroup o = read_group(r, group, total);
    c.groups.push_back(o);
    total += o.size;
    amsgrad_of.insert(amsgrad_of.end(), static_cast<size_t>(o.size), o.amsgrad);
  }
  for (const auto& m : r.members(kOptimizer))
    if (!expected_members.count(m)) r.fail("optimizer/" + m, "is not part of an optimizer");
  return amsgrad_of;
}

// The state of parameter `index`, stored under `object`, with its moments checked.
AdamSlot read_slot(const Reader& r, int64_t index, const std::string& object, bool amsgrad) {
  const std::string entry = Reader::entry_of(object);
  const int64_t step = r.int_attr(object, "step");
  if (step < 0) r.fail(entry, "has step " + std::to_string(step) + " (expected >= 0)");
  AdamSlot slot;
  slot.index = index;
  slot.step = step;
  slot.parameter = r.file().attr_string(object, "parameter");
  const std::vector<std::string> present = r.members(object);
  for (const auto& p : present)
    if (std::find(std::begin(kMoments), std::end(kMoments) - (amsgrad ? 0 : 1), p) ==
        std::end(kMoments) - (amsgrad ? 0 : 1))
      r.fail(entry + "/" + clip(p), "is not part of Adam's state");
  for (int k = 0; k < (amsgrad ? 3 : 2); ++k) {
    const std::string field = kMoments[k];
    if (std::find(present.begin(), present.end(), field) == present.end())
      r.fail(entry + "/" + field, "is missing");
    torch::Tensor t = r.tensor(object + "/" + field);
    if (k > 0 && (t < 0).any().item<bool>())
      r.fail(entry + "/" + field, "has a negative value (a mean of squares)");
    (k == 0 ? slot.exp_avg : k == 1 ? slot.exp_avg_sq : slot.max_exp_avg_sq) = t;
  }
  return slot;
}

// The optimizer's per-parameter states into c.slots, by ascending parameter index.
void read_slots(const Reader& r, const std::vector<bool>& amsgrad_of, int64_t total,
                CheckpointContents& c) {
  std::vector<std::pair<int64_t, std::string>> indices;
  for (const auto& m : counted_members(r, kState)) {
    if (!is_index(m) || std::stoll(m) >= total)
      r.fail("optimizer/state/" + clip(m),
             "is not a parameter index (the optimizer has " + std::to_string(total) + ")");
    indices.emplace_back(std::stoll(m), m);
  }
  std::sort(indices.begin(), indices.end());
  for (const auto& [index, m] : indices)
    c.slots.push_back(
        read_slot(r, index, std::string(kState) + "/" + m, amsgrad_of[static_cast<size_t>(index)]));
}

// The average of the parameters: its settings and one floating-point entry per parameter.
void read_ema(const Reader& r, CheckpointContents& c) {
  const std::vector<std::string> entries = counted_members(r, kEma);
  if (entries.empty()) r.fail("ema", "has no entry");
  c.ema_decay = r.double_attr(kEma, "decay");
  if (!(c.ema_decay > 0 && c.ema_decay < 1))
    r.fail("ema", "has decay " + std::to_string(c.ema_decay) + " (expected in (0, 1))");
  c.ema_updates = r.int_attr(kEma, "updates");
  if (c.ema_updates < 0)
    r.fail("ema", "has updates " + std::to_string(c.ema_updates) + " (expected >= 0)");
  for (const auto& m : entries) c.ema.push_back({m, r.tensor(std::string(kEma) + "/" + m)});
}

CheckpointContents read_contents(const Reader& r) {
  CheckpointContents c;
  const std::string kind = read_kind(r);
  c.training = kind == "training";
  for (const auto& m : r.members("/"))
    if (!(m == "model" || (c.training && (m == "optimizer" || m == "ema"))))
      r.fail(m, "is not part of a " + kind + " checkpoint (unexpected entry)");
  read_model(r, c);
  if (!c.training) return c;
  read_training_state(r, c.state);
  int64_t total = 0;
  const std::vector<bool> amsgrad_of = read_groups(r, c, total);
  read_slots(r, amsgrad_of, total, c);
  if (r.file().exists(kEma)) read_ema(r, c);
  return c;
}

// Each averaged entry names a floating-point model entry and has its shape and dtype.
void check_ema(const Reader& r, const CheckpointContents& c) {
  std::map<std::string, const torch::Tensor*> model;
  for (const auto& t : c.model) model.emplace(t.name, &t.value);
  for (const auto& e : c.ema) {
    const auto it = model.find(e.name);
    if (it == model.end()) r.fail("ema/" + clip(e.name), "names no entry of the model");
    const torch::Tensor& p = *it->second;
    if (!p.is_floating_point() || e.value.sizes() != p.sizes() ||
        e.value.scalar_type() != p.scalar_type())
      r.fail("ema/" + clip(e.name),
             "has shape " + shape_text(e.value.sizes(), e.value.scalar_type()) +
                 ", its model entry " + shape_text(p.sizes(), p.scalar_type()));
  }
}

// Each optimizer state belongs to a distinct model entry and has its shape and dtype. (Apart
// from read_contents so that a loader compares the model with the module first: a checkpoint of
// another model is named by its model entries.)
void check_slots(const Reader& r, const CheckpointContents& c) {
  std::map<std::string, const torch::Tensor*> model;
  for (const auto& t : c.model) model.emplace(t.name, &t.value);
  std::set<std::string> named;
  for (const AdamSlot& a : c.slots) {
    const std::string entry = "optimizer/state/" + std::to_string(a.index);
    const auto it = model.find(a.parameter);
    if (it == model.end())
      r.fail(entry, "names parameter '" + clip(a.parameter) + "', which the model has no entry of");
    if (!named.insert(a.parameter).second)
      r.fail(entry, "names parameter '" + clip(a.parameter) + "' a second time");
    const torch::Tensor& p = *it->second;
    for (const auto& [field, t] :
         {std::make_pair("exp_avg", &a.exp_avg), std::make_pair("exp_avg_sq", &a.exp_avg_sq),
          std::make_pair("max_exp_avg_sq", &a.max_exp_avg_sq)})
      if (t->defined() && (t->sizes() != p.sizes() || t->scalar_type() != p.scalar_type()))
        r.fail(entry + "/" + field, "has shape " + shape_text(t->sizes(), t->scalar_type()) +
                                        ", its parameter '" + clip(a.parameter) + "' " +
                                        shape_text(p.sizes(), p.scalar_type()));
  }
}

// The module's floating-point parameters, each with its averaged value, when the checkpoint has
// an average (else none): it must cover exactly those parameters.
std::vector<std::pair<torch::Tensor, const torch::Tensor*>> averaged_parameters(
    const Reader& r, const CheckpointContents& c, torch::nn::Module& module) {
  std::vector<std::pair<torch::Tensor, const torch::Tensor*>> averaged;
  if (c.ema.empty()) return averaged;
  std::map<std::string, const torch::Tensor*> by_name;
  for (const auto& e : c.ema) by_name.emplace(e.name, &e.value);
  for (const auto& p : module.named_parameters(/*recurse=*/true)) {
    if (!p.value().is_floating_point()) continue;
    const auto it = by_name.find(p.key());
    if (it == by_name.end()) r.fail("has no entry 'ema/" + p.key() + "' (the average is partial)");
    averaged.emplace_back(p.value(), it->second);
  }
  if (averaged.size() != c.ema.size()) r.fail("ema", "averages an entry that is not a parameter");
  return averaged;
}

// The checkpoint's average (checked by averaged_parameters) in the order of `ema`.
std::vector<torch::Tensor> ordered_averages(const Reader& r, const CheckpointContents& c,
                                            const ParameterEma& ema) {
  std::map<std::string, torch::Tensor> values;
  for (const auto& e : c.ema) values.emplace(e.name, e.value);
  std::vector<torch::Tensor> ordered;
  for (const auto& [entry, value] : ema.averages()) {
    const auto it = values.find(entry);
    if (it == values.end()) r.fail("has no entry 'ema/" + entry + "'");
    ordered.push_back(it->second);
  }
  return ordered;
}

}  // namespace

std::string read_checkpoint_bytes(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(path + ": checkpoint not found");
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(path + ": not a regular file (a checkpoint is one)");
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(path + ": cannot read (" + ec.message() + ")");
  std::ifstream in(path, std::ios::binary);
  std::string bytes(static_cast<size_t>(size), '\0');
  if (!in || !in.read(bytes.data(), static_cast<std::streamsize>(size)))
    throw InputError(path + ": cannot read");
  return bytes;
}

CheckpointContents checkpoint_contents(const torch::nn::Module& module,
                                       const torch::optim::Adam* optimizer,
                                       const TrainingState* state, const ParameterEma* ema) {
  if ((optimizer == nullptr) != (state == nullptr))
    throw std::invalid_argument("checkpoint_contents: optimizer and state go together");
  if (ema && !optimizer)
    throw std::invalid_argument("checkpoint_contents: an average is part of a training checkpoint");
  CheckpointContents c;
  for (const auto& [name, value] : module_entries(module)) c.model.push_back({name, value});
  if (!optimizer) return c;
  c.training = true;
  c.state = *state;
  const std::vector<std::string> names = optimizer_parameter_names(module, *optimizer);
  int64_t index = 0;
  for (const auto& group : optimizer->param_groups()) {
    const auto& o = static_cast<const torch::optim::AdamOptions&>(group.options());
    c.groups.push_back({o.lr(), std::get<0>(o.betas()), std::get<1>(o.betas()), o.eps(),
                        o.weight_decay(), o.amsgrad(),
                        static_cast<int64_t>(group.params().size())});
    for (const auto& p : group.params()) {
      const auto it = optimizer->state().find(impl_key(p));
      if (it != optimizer->state().end()) {
        const auto& s = static_cast<const torch::optim::AdamParamState&>(*it->second);
        AdamSlot slot;
        slot.index = index;
        slot.parameter = names[static_cast<size_t>(index)];
        slot.step = s.step();
        slot.exp_avg = s.exp_avg();
        slot.exp_avg_sq = s.exp_avg_sq();
        if (o.amsgrad()) slot.max_exp_avg_sq = s.max_exp_avg_sq();
        c.slots.push_back(std::move(slot));
      }
      ++index;
    }
  }
  if (ema) {
    for (const auto& [name, value] : ema->averages()) c.ema.push_back({name, value});
    c.ema_decay = ema->decay();
    c.ema_updates = ema->updates();
  }
  return c;
}

void write_checkpoint_contents(const std::string& path, const CheckpointContents& c) {
  AtomicOutput out(path);
  {
    H5File f = H5File::create_checksummed(out.temp_path());
    Writer w(f);
    f.set_attr("/", "format", std::string(kCheckpointFormat));
    f.set_attr("/", "version", kCheckpointVersion);
    f.set_attr("/", "kind", std::string(c.training ? "training" : "module"));
    f.create_group(kModel);
    f.set_attr(kModel, "count", static_cast<int64_t>(c.model.size()));
    for (const auto& t : c.model) {
      if (t.name.empty() || t.name.find('/') != std::string::npos)
        throw IoError(path + ": module entry '" + clip(t.name) + "' cannot be an HDF5 name");
      w.tensor(std::string(kModel) + "/" + t.name, t.value);
    }
    if (c.training) {
      f.set_attr("/", "step", c.state.step);
      f.set_attr("/", "wall_s", c.state.wall_s);
      f.set_attr("/", "loss", c.state.loss);
      f.set_attr("/", "valid_loss", c.state.valid_loss);
      f.set_attr("/", "valid_zero_prediction", c.state.valid_zero_prediction);
      f.create_group(kState);
      f.set_attr(kState, "count", static_cast<int64_t>(c.slots.size()));
      f.set_attr(kOptimizer, "groups", static_cast<int64_t>(c.groups.size()));
      for (size_t g = 0; g < c.groups.size(); ++g) {
        const AdamGroup& o = c.groups[g];
        const std::string object = std::string(kOptimizer) + "/group_" + std::to_string(g);
        f.create_group(object);
        f.set_attr(object, "lr", o.lr);
        f.set_attr(object, "beta1", o.beta1);
        f.set_attr(object, "beta2", o.beta2);
        f.set_attr(object, "eps", o.eps);
        f.set_attr(object, "weight_decay", o.weight_decay);
        f.set_attr(object, "amsgrad", static_cast<int64_t>(o.amsgrad));
        f.set_attr(object, "size", o.size);
      }
      for (const AdamSlot& a : c.slots) {
        const std::string entry = std::string(kState) + "/" + std::to_string(a.index);
        f.create_group(entry);
        f.set_attr(entry, "step", a.step);
        f.set_attr(entry, "parameter", a.parameter);
        w.tensor(entry + "/exp_avg", a.exp_avg);
        w.tensor(entry + "/exp_avg_sq", a.exp_avg_sq);
        if (a.max_exp_avg_sq.defined()) w.tensor(entry + "/max_exp_avg_sq", a.max_exp_avg_sq);
      }
      if (!c.ema.empty()) {
        f.create_group(kEma);
        f.set_attr(kEma, "count", static_cast<int64_t>(c.ema.size()));
        f.set_attr(kEma, "decay", c.ema_decay);
        f.set_attr(kEma, "updates", c.ema_updates);
        for (const auto& t : c.ema) {
          if (t.name.empty() || t.name.find('/') != std::string::npos)
            throw IoError(path + ": averaged entry '" + clip(t.name) + "' cannot be an HDF5 name");
          w.tensor(std::string(kEma) + "/" + t.name, t.value);
        }
      }
    }
    f.close();
  }
  out.commit();
}

void save_checkpoint_file(const std::string& path, const torch::nn::Module& module,
                          const torch::optim::Adam* optimizer, const TrainingState* state,
                          const ParameterEma* ema) {
  write_checkpoint_contents(path, checkpoint_contents(module, optimizer, state, ema));
}

CheckpointContents read_checkpoint_contents(const std::string& name, const std::string& bytes) {
  const Reader r(name, bytes);
  CheckpointContents c = read_contents(r);
  check_slots(r, c);
  check_ema(r, c);
  return c;
}

TrainingState load_checkpoint_image(const std::string& name, const std::string& bytes,
                                    torch::nn::Module& module, torch::optim::Adam* optimizer,
                                    bool require_training, ParameterEma* ema) {
  const Reader r(name, bytes);
  const CheckpointContents c = read_contents(r);
  if ((optimizer || require_training) && !c.training)
    r.fail(
        "a module checkpoint (no optimizer state or step): training needs a training "
        "checkpoint");
  std::map<std::string, const torch::Tensor*> stored;
  for (const auto& t : c.model) stored.emplace(t.name, &t.value);

  // The module, entry by entry in its own order: the first difference is the one named.
  const auto entries = module_entries(module);
  std::vector<std::pair<torch::Tensor, const torch::Tensor*>> copies;
  std::set<std::string> expected;
  const char* const other = " (checkpoint of a different model configuration?)";
  for (const auto& [entry, target] : entries) {
    expected.insert(entry);
    const auto it = stored.find(entry);
    if (it == stored.end()) r.fail("has no entry 'model/" + entry + "'" + other);
    const torch::Tensor& value = *it->second;
    if (value.sizes() != target.sizes() || value.scalar_type() != target.scalar_type())
      r.fail("model/" + entry, "has shape " + shape_text(value.sizes(), value.scalar_type()) +
                                   ", the model expects " +
                                   shape_text(target.sizes(), target.scalar_type()) + other);
    copies.emplace_back(target, &value);
  }
  for (const auto& t : c.model)
    if (!expected.count(t.name))
      r.fail("model/" + clip(t.name), std::string("is unexpected") + other);
  check_slots(r, c);
  check_ema(r, c);

  // To predict, the average is the model: it replaces the training weights.
  const std::vector<std::pair<torch::Tensor, const torch::Tensor*>> averaged =
      averaged_parameters(r, c, module);
  const bool predict_with_average = !optimizer && !averaged.empty();
  const std::vector<torch::Tensor> ema_values = ema && optimizer && !averaged.empty()
                                                    ? ordered_averages(r, c, *ema)
                                                    : std::vector<torch::Tensor>{};

  // The optimizer: the same groups, each parameter's state (if any) stored for that parameter.
  struct Slot {
    std::string key;
    std::unique_ptr<torch::optim::AdamParamState> state;
  };
  std::vector<Slot> slots;
  if (optimizer) {
    const std::vector<std::string> names = optimizer_parameter_names(module, *optimizer);
    auto& groups = optimizer->param_groups();
    if (c.groups.size() != groups.size())
      r.fail("optimizer", "has " + std::to_string(c.groups.size()) +
                              " parameter groups, the "
                              "optimizer " +
                              std::to_string(groups.size()));
    std::vector<std::string> keys;
    for (size_t g = 0; g < groups.size(); ++g) {
      if (static_cast<size_t>(c.groups[g].size) != groups[g].params().size())
        r.fail("optimizer/group_" + std::to_string(g),
               "has " + std::to_string(c.groups[g].size) + " parameters, the optimizer " +
                   std::to_string(groups[g].params().size()));
      for (const auto& p : groups[g].params()) keys.push_back(impl_key(p));
    }
    for (const AdamSlot& a : c.slots) {
      const size_t index = static_cast<size_t>(a.index);
      if (a.parameter != names[index])
        r.fail("optimizer/state/" + std::to_string(a.index),
               "belongs to parameter '" + clip(a.parameter) + "', the optimizer's parameter " +
                   std::to_string(a.index) + " is '" + names[index] + "'");
      auto s = std::make_unique<torch::optim::AdamParamState>();
      s->step(a.step).exp_avg(a.exp_avg).exp_avg_sq(a.exp_avg_sq);
      if (a.max_exp_avg_sq.defined()) s->max_exp_avg_sq(a.max_exp_avg_sq);
      slots.push_back({keys[index], std::move(s)});
    }
  }

  // Everything checked: copy.
  {
    torch::NoGradGuard no_grad;
    for (auto& [target, value] : copies) target.copy_(*value);
    if (predict_with_average)
      for (auto& [target, value] : averaged) target.copy_(*value);
  }
  if (optimizer) {
    for (size_t g = 0; g < optimizer->param_groups().size(); ++g) {
      auto& o = static_cast<torch::optim::AdamOptions&>(optimizer->param_groups()[g].options());
      const AdamGroup& v = c.groups[g];
      o.lr(v.lr).betas(std::make_tuple(v.beta1, v.beta2)).eps(v.eps).weight_decay(v.weight_decay);
      o.amsgrad(v.amsgrad);
    }
    optimizer->state().clear();
    for (auto& slot : slots) optimizer->state()[slot.key] = std::move(slot.state);
    if (ema && ema_values.empty()) ema->restart();  // a checkpoint without an average
    if (ema && !ema_values.empty()) ema->restore(c.ema_updates, ema_values);
  }
  return c.training ? c.state : TrainingState{};
}

void save_module(const torch::nn::Module& module, const std::string& path) {
  save_checkpoint_file(path, module, nullptr, nullptr);
}

void load_module(torch::nn::Module& module, const std::string& path) {
  load_checkpoint_image(path, read_checkpoint_bytes(path), module, nullptr);
}

}  // namespace bsms
