#include "dimr/nn/bsp_dataset.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "dimr/core/binary_io.h"
#include "dimr/core/error.h"

namespace dimr::nn {
namespace {

// "DIMRBSPD" | u32 version | i32 R | u64 count | count x { i32 class | u32 id length | id |
// grid bits | target grid bits (R^3 each, bit i of byte i / 8, x fastest) | u64 K | 3K u16
// inside points | u64 L | 3L u16 outside points } (coordinates quantised to 16 bits).
constexpr char kMagic[] = "DIMRBSPD";
constexpr std::uint32_t kVersion = 2;

void PutBits(BinaryWriter* out, const std::vector<std::uint8_t>& grid) {
  std::string bits((grid.size() + 7) / 8, '\0');
  for (std::size_t i = 0; i < grid.size(); ++i) {
    if (grid[i]) bits[i / 8] = static_cast<char>(bits[i / 8] | (1 << (i % 8)));
  }
  out->PutString(bits);
}

void GetBits(BinaryReader* r, std::size_t cells, std::vector<std::uint8_t>* grid,
             const std::string& what) {
  const char* bits = r->Bytes((cells + 7) / 8, what.c_str());
  grid->assign(cells, 0);
  for (std::size_t i = 0; i < cells; ++i) (*grid)[i] = (bits[i / 8] >> (i % 8)) & 1;
}

// Coordinates in [-1, 1] quantised to 16 bits (step 3.1e-5).
std::uint16_t Quantize(float v) {
  const float c = std::min(1.0f, std::max(-1.0f, v));
  return static_cast<std::uint16_t>(std::lround((c + 1.0f) * 0.5f * 65535.0f));
}
float Dequantize(std::uint16_t q) { return static_cast<float>(q) / 65535.0f * 2.0f - 1.0f; }

void PutPoints(BinaryWriter* out, const std::vector<float>& pts) {
  out->Put(static_cast<std::uint64_t>(pts.size() / 3));
  for (float v : pts) out->Put(Quantize(v));
}

void GetPoints(BinaryReader* r, std::vector<float>* pts, const std::string& what) {
  const std::size_t n = r->Count(r->Get<std::uint64_t>((what + " count").c_str()), 6, what.c_str());
  std::vector<std::uint16_t> q;
  r->GetArray(3 * n, &q, what.c_str());
  pts->resize(3 * n);
  for (std::size_t i = 0; i < q.size(); ++i) (*pts)[i] = Dequantize(q[i]);
}

}  // namespace

float QuantizeBspCoordinate(float v) { return Dequantize(Quantize(v)); }

void BspDataset::Save(const std::string& path) const {
  BinaryWriter out;
  out.PutString(kMagic);
  out.Put(kVersion);
  out.Put(static_cast<std::int32_t>(resolution));
  out.Put(static_cast<std::uint64_t>(samples.size()));
  const std::size_t cells = static_cast<std::size_t>(resolution) * resolution * resolution;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const BspSample& s = samples[i];
    if (s.grid.size() != cells || s.iou_grid.size() != cells || s.inside_points.size() % 3 ||
        s.outside_points.size() % 3) {
      throw InvalidArgument("BspDataset::Save(" + path + "): sample " + std::to_string(i) +
                            " has inconsistent sizes");
    }
    out.Put(static_cast<std::int32_t>(s.cad_class));
    out.Put(static_cast<std::uint32_t>(s.model_id.size()));
    out.PutString(s.model_id);
    PutBits(&out, s.grid);
    PutBits(&out, s.iou_grid);
    PutPoints(&out, s.inside_points);
    PutPoints(&out, s.outside_points);
  }
  out.WriteFile(path);
}

BspDataset BspDataset::Load(const std::string& path) {
  const std::string bytes = ReadFileBytes(path);
  BinaryReader r(path, bytes);
  r.ExpectMagic(kMagic, "a dimr BSP dataset");
  const auto version = r.Get<std::uint32_t>("version");
  if (version != kVersion) r.Fail("unsupported dataset version " + std::to_string(version));
  BspDataset data;
  data.resolution = r.Get<std::int32_t>("resolution");
  if (data.resolution < 2 || data.resolution > 512) {
    r.Fail("resolution " + std::to_string(data.resolution) + " out of range");
  }
  const std::size_t cells =
      static_cast<std::size_t>(data.resolution) * data.resolution * data.resolution;
  // Each sample holds at least its two bit grids and 24 bytes of class, id length and counts.
  const std::size_t count =
      r.Count(r.Get<std::uint64_t>("sample count"), 2 * ((cells + 7) / 8) + 24, "samples");
  data.samples.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::string where = "sample " + std::to_string(i);
    BspSample& s = data.samples[i];
    s.cad_class = r.Get<std::int32_t>((where + " class").c_str());
    const auto id_len = r.Get<std::uint32_t>((where + " id length").c_str());
    s.model_id = r.GetString(id_len, (where + " id").c_str());
    GetBits(&r, cells, &s.grid, where + " grid");
    GetBits(&r, cells, &s.iou_grid, where + " target grid");
    GetPoints(&r, &s.inside_points, where + " inside points");
    GetPoints(&r, &s.outside_points, where + " outside points");
  }
  r.ExpectEnd("the last sample");
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
