#include "dimr/nn/bsp_dataset.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::nn {
namespace {

constexpr char kMagic[8] = {'D', 'I', 'M', 'R', 'B', 'S', 'P', 'D'};
constexpr std::uint32_t kVersion = 2;

template <typename T>
void Put(std::string* out, const T& v) {
  out->append(reinterpret_cast<const char*>(&v), sizeof(T));
}

class Reader {
 public:
  Reader(const std::string& bytes, const std::string& path) : bytes_(bytes), path_(path) {}
  template <typename T>
  T Get(const std::string& what) {
    Need(sizeof(T), what);
    T v;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  void Bytes(void* dst, std::size_t n, const std::string& what) {
    Need(n, what);
    if (n) std::memcpy(dst, bytes_.data() + pos_, n);
    pos_ += n;
  }
  void Need(std::size_t n, const std::string& what) const {
    if (n > bytes_.size() - pos_) {
      throw ParseError(path_, what + ": needs " + std::to_string(n) + " bytes, only " +
                                  std::to_string(bytes_.size() - pos_) + " left (truncated file)");
    }
  }
  bool AtEnd() const { return pos_ == bytes_.size(); }

 private:
  const std::string& bytes_;
  const std::string& path_;
  std::size_t pos_ = 0;
};

}  // namespace

namespace {

void PutBits(std::string* out, const std::vector<std::uint8_t>& grid) {
  std::string bits((grid.size() + 7) / 8, '\0');
  for (std::size_t i = 0; i < grid.size(); ++i) {
    if (grid[i]) bits[i / 8] = static_cast<char>(bits[i / 8] | (1 << (i % 8)));
  }
  out->append(bits);
}

void GetBits(Reader* r, std::size_t cells, std::vector<std::uint8_t>* grid,
             const std::string& what) {
  std::string bits((cells + 7) / 8, '\0');
  r->Bytes(bits.data(), bits.size(), what);
  grid->assign(cells, 0);
  for (std::size_t i = 0; i < cells; ++i) (*grid)[i] = (bits[i / 8] >> (i % 8)) & 1;
}

// Coordinates in [-1, 1] quantised to 16 bits (step 3.1e-5).
std::uint16_t Quantize(float v) {
  const float c = std::min(1.0f, std::max(-1.0f, v));
  return static_cast<std::uint16_t>(std::lround((c + 1.0f) * 0.5f * 65535.0f));
}
float Dequantize(std::uint16_t q) { return static_cast<float>(q) / 65535.0f * 2.0f - 1.0f; }

void PutPoints(std::string* out, const std::vector<float>& pts) {
  Put(out, static_cast<std::uint64_t>(pts.size() / 3));
  for (float v : pts) Put(out, Quantize(v));
}

void GetPoints(Reader* r, std::size_t file_size, std::vector<float>* pts, const std::string& path,
               const std::string& what) {
  const auto n = r->Get<std::uint64_t>(what + " count");
  if (n > file_size / 6) throw ParseError(path, what + ": absurd point count " + std::to_string(n));
  r->Need(n * 6, what);
  pts->resize(n * 3);
  for (auto& v : *pts) v = Dequantize(r->Get<std::uint16_t>(what));
}

}  // namespace

float QuantizeBspCoordinate(float v) { return Dequantize(Quantize(v)); }

void BspDataset::Save(const std::string& path) const {
  std::string out;
  out.append(kMagic, sizeof(kMagic));
  Put(&out, kVersion);
  Put(&out, static_cast<std::int32_t>(resolution));
  Put(&out, static_cast<std::uint64_t>(samples.size()));
  const std::size_t cells = static_cast<std::size_t>(resolution) * resolution * resolution;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const BspSample& s = samples[i];
    if (s.grid.size() != cells || s.iou_grid.size() != cells || s.inside_points.size() % 3 ||
        s.outside_points.size() % 3) {
      throw InvalidArgument("BspDataset::Save(" + path + "): sample " + std::to_string(i) +
                            " has inconsistent sizes");
    }
    Put(&out, static_cast<std::int32_t>(s.cad_class));
    Put(&out, static_cast<std::uint32_t>(s.model_id.size()));
    out.append(s.model_id);
    PutBits(&out, s.grid);
    PutBits(&out, s.iou_grid);
    PutPoints(&out, s.inside_points);
    PutPoints(&out, s.outside_points);
  }
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw Error("cannot open '" + path + "' for writing");
  f.write(out.data(), static_cast<std::streamsize>(out.size()));
  if (!f) throw Error("failed writing '" + path + "'");
}

BspDataset BspDataset::Load(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ParseError(path, "cannot open file");
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  Reader r(bytes, path);
  char magic[8];
  r.Bytes(magic, sizeof(magic), "header");
  if (std::memcmp(magic, kMagic, sizeof(kMagic)) != 0) {
    throw ParseError(path, "not a dimr BSP dataset (bad magic)");
  }
  const auto version = r.Get<std::uint32_t>("version");
  if (version != kVersion) {
    throw ParseError(path, "unsupported dataset version " + std::to_string(version));
  }
  BspDataset data;
  data.resolution = r.Get<std::int32_t>("resolution");
  if (data.resolution < 2 || data.resolution > 512) {
    throw ParseError(path, "resolution " + std::to_string(data.resolution) + " out of range");
  }
  const auto count = r.Get<std::uint64_t>("sample count");
  const std::size_t cells =
      static_cast<std::size_t>(data.resolution) * data.resolution * data.resolution;
  // Each sample needs at least its two bit grids; reject absurd counts before allocating.
  if (count > bytes.size() / (2 * ((cells + 7) / 8) + 24)) {
    throw ParseError(path,
                     "claims " + std::to_string(count) + " samples, more than the file holds");
  }
  data.samples.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::string where = "sample " + std::to_string(i);
    BspSample& s = data.samples[i];
    s.cad_class = r.Get<std::int32_t>(where + " class");
    const auto id_len = r.Get<std::uint32_t>(where + " id length");
    r.Need(id_len, where + " id");
    s.model_id.resize(id_len);
    r.Bytes(s.model_id.data(), id_len, where + " id");
    GetBits(&r, cells, &s.grid, where + " grid");
    GetBits(&r, cells, &s.iou_grid, where + " target grid");
    GetPoints(&r, bytes.size(), &s.inside_points, path, where + " inside points");
    GetPoints(&r, bytes.size(), &s.outside_points, path, where + " outside points");
  }
  if (!r.AtEnd()) throw ParseError(path, "trailing bytes after the last sample");
  return data;
}

void BspDataset::Append(const BspDataset& other) {
  if (other.resolution != resolution) {
    throw InvalidArgument("cannot append a dataset of resolution " +
                          std::to_string(other.resolution) + " to one of resolution " +
                          std::to_string(resolution));
  }
  samples.insert(samples.end(), other.samples.begin(), other.samples.end());
}

}  // namespace dimr::nn
