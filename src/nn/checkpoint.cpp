// Named-tensor checkpoint format:
//   "DIMRCKPT" | u32 version (1) | u64 count |
//   count x { u32 name_len | name | u8 dtype | u32 ndim | i64 dims[ndim] | u64 nbytes | data } |
//   u64 FNV-1a-64 of every preceding byte.
// Little-endian host order (x86-64 / aarch64).
#include "dimr/nn/checkpoint.h"

#include <cstdint>
#include <cstring>
#include <map>
#include <set>
#include <sstream>

#include "dimr/core/binary_io.h"
#include "dimr/core/error.h"
#include "dimr/core/hash.h"

namespace dimr::nn {
namespace {

constexpr char kMagic[8] = {'D', 'I', 'M', 'R', 'C', 'K', 'P', 'T'};
constexpr uint32_t kVersion = 1;
constexpr uint32_t kMaxNameLen = 4096;
constexpr uint32_t kMaxDims = 16;

enum DType : uint8_t { kF32 = 0, kF64 = 1, kF16 = 2, kI64 = 3 };

std::string ShapeStr(at::IntArrayRef s) {
  std::ostringstream os;
  os << s;
  return os.str();
}

}  // namespace

NamedTensors ModuleState(const torch::nn::Module& module) {
  NamedTensors out;
  for (const auto& p : module.named_parameters(true)) out.emplace_back(p.key(), p.value());
  for (const auto& b : module.named_buffers(true)) out.emplace_back(b.key(), b.value());
  return out;
}

void WriteCheckpoint(const NamedTensors& tensors, const std::string& path, bool half) {
  BinaryWriter buf;
  buf.PutBytes(kMagic, sizeof(kMagic));
  buf.Put<uint32_t>(kVersion);
  buf.Put<uint64_t>(tensors.size());
  for (const auto& [name, tensor] : tensors) {
    at::Tensor t = tensor.detach().to(at::kCPU).contiguous();
    uint8_t code;
    if (t.scalar_type() == at::kLong) {
      code = kI64;
    } else if (t.scalar_type() == at::kInt) {
      t = t.to(at::kLong);
      code = kI64;
    } else if (half && at::isFloatingType(t.scalar_type())) {
      t = t.to(at::kHalf);
      code = kF16;
    } else if (t.scalar_type() == at::kDouble) {
      code = kF64;
    } else if (t.scalar_type() == at::kHalf) {
      code = kF16;
    } else if (t.scalar_type() == at::kFloat) {
      code = kF32;
    } else {
      throw InvalidArgument("checkpoint: tensor '" + name + "' has unsupported dtype " +
                            std::string(c10::toString(t.scalar_type())));
    }
    buf.Put<uint32_t>(static_cast<uint32_t>(name.size()));
    buf.PutString(name);
    buf.Put<uint8_t>(code);
    buf.Put<uint32_t>(static_cast<uint32_t>(t.dim()));
    for (int64_t d : t.sizes()) buf.Put<int64_t>(d);
    const uint64_t nbytes = static_cast<uint64_t>(t.numel()) * t.element_size();
    buf.Put<uint64_t>(nbytes);
    buf.PutBytes(t.data_ptr(), nbytes);
  }
  buf.Put<uint64_t>(Fnv1a(buf.bytes().data(), buf.size()));
  buf.WriteFile(path);
}

NamedTensors ReadCheckpoint(const std::string& path) {
  const std::string data = ReadFileBytes(path);
  if (data.size() < sizeof(kMagic) + 4 + 8 + 8) {
    throw ParseError(path, "truncated: " + std::to_string(data.size()) +
                               " bytes is smaller than a checkpoint header");
  }
  if (std::memcmp(data.data(), kMagic, sizeof(kMagic)) != 0) {
    throw ParseError(path, "not a dimr checkpoint (bad magic)");
  }
  const size_t body = data.size() - 8;
  BinaryReader r(path, std::string_view(data.data(), body));  // the checksum is not read by r
  r.Bytes(sizeof(kMagic), "magic");
  const uint32_t version = r.Get<uint32_t>("version");
  if (version != kVersion) {
    throw ParseError(path, "unsupported checkpoint version " + std::to_string(version));
  }
  const uint64_t count = r.Get<uint64_t>("tensor count");
  // Each entry needs at least 4 + 1 + 4 + 8 bytes.
  r.Count(count, 17, "tensors");
  NamedTensors out;
  std::set<std::string> seen;
  for (uint64_t i = 0; i < count; ++i) {
    const std::string where = "tensor " + std::to_string(i);
    const uint32_t name_len = r.Get<uint32_t>("name length");
    if (name_len == 0 || name_len > kMaxNameLen) {
      throw ParseError(path, where + ": bad name length " + std::to_string(name_len));
    }
    std::string name(r.Bytes(name_len, "name"), name_len);
    if (!seen.insert(name).second) throw ParseError(path, "duplicate key '" + name + "'");
    const uint8_t code = r.Get<uint8_t>("dtype");
    at::ScalarType st;
    switch (code) {
      case kF32:
        st = at::kFloat;
        break;
      case kF64:
        st = at::kDouble;
        break;
      case kF16:
        st = at::kHalf;
        break;
      case kI64:
        st = at::kLong;
        break;
      default:
        throw ParseError(path, "'" + name + "': unknown dtype code " + std::to_string(code));
    }
    const uint32_t ndim = r.Get<uint32_t>("ndim");
    if (ndim > kMaxDims) {
      throw ParseError(path, "'" + name + "': " + std::to_string(ndim) + " dimensions");
    }
    std::vector<int64_t> dims(ndim);
    uint64_t numel = 1;
    for (uint32_t d = 0; d < ndim; ++d) {
      dims[d] = r.Get<int64_t>("dims");
      if (dims[d] < 0 || (dims[d] > 0 && numel > (uint64_t{1} << 40) / dims[d])) {
        throw ParseError(path, "'" + name + "': bad dimension " + std::to_string(dims[d]));
      }
      numel *= static_cast<uint64_t>(dims[d]);
    }
    const uint64_t nbytes = r.Get<uint64_t>("byte count");
    if (nbytes != numel * c10::elementSize(st)) {
      throw ParseError(path, "'" + name + "': byte count " + std::to_string(nbytes) +
                                 " does not match shape " + ShapeStr(dims));
    }
    const char* src = r.Bytes(nbytes, "tensor data");
    at::Tensor t = at::empty(dims, st);
    if (nbytes) std::memcpy(t.data_ptr(), src, nbytes);
    out.emplace_back(std::move(name), std::move(t));
  }
  if (r.pos() != body) {
    throw ParseError(path, std::to_string(body - r.pos()) + " unexpected bytes after the tensors");
  }
  uint64_t stored;
  std::memcpy(&stored, data.data() + body, 8);
  if (stored != Fnv1a(data.data(), body)) {
    throw ParseError(path, "checksum mismatch (file corrupt)");
  }
  return out;
}

void SaveCheckpoint(const torch::nn::Module& module, const std::string& path, bool half) {
  WriteCheckpoint(ModuleState(module), path, half);
}

void LoadCheckpoint(torch::nn::Module& module, const std::string& path) {
  NamedTensors file = ReadCheckpoint(path);
  NamedTensors model = ModuleState(module);
  std::map<std::string, at::Tensor> by_name(file.begin(), file.end());
  std::set<std::string> model_keys;
  for (const auto& [name, t] : model) {
    model_keys.insert(name);
    auto it = by_name.find(name);
    if (it == by_name.end()) {
      throw ParseError(path,
                       "missing key '" + name + "' (model shape " + ShapeStr(t.sizes()) + ")");
    }
    if (it->second.sizes() != t.sizes()) {
      throw ParseError(path, "shape mismatch for key '" + name + "': checkpoint " +
                                 ShapeStr(it->second.sizes()) + " vs model " + ShapeStr(t.sizes()));
    }
  }
  for (const auto& [name, t] : file) {
    if (!model_keys.count(name)) {
      throw ParseError(path, "unexpected key '" + name + "' (checkpoint shape " +
                                 ShapeStr(t.sizes()) + ") not in the model");
    }
  }
  at::NoGradGuard no_grad;
  for (auto& [name, t] : model) t.copy_(by_name.at(name).to(t.device(), t.scalar_type()));
}

}  // namespace dimr::nn
