// NumPy .npy / .npz reading (and .npz writing, uncompressed), for the reference's processed
// ScanNet data (`processed_data/<scene>/data.npz`: mesh_vertices, semantic_labels,
// instance_labels) used by the PCR ground truth. Little-endian C-order arrays of bool, int8..64,
// uint8..64, float32/64; ZIP stored entries always, deflated ones when built with zlib.
// Malformed files throw dimr::ParseError naming the file and the entry.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace dimr::eval {

struct NpyArray {
  std::string dtype;  // numpy descr without byte order, e.g. "f8", "u1", "i4", "b1"
  std::vector<std::int64_t> shape;
  std::vector<double> values;  // every element converted to double (C order)
  std::int64_t size() const;   // product of shape
};

// Parses one .npy file held in memory; `source` names it in errors.
NpyArray ParseNpy(const std::uint8_t* data, std::size_t size, const std::string& source);
// One .npy file (numpy.save). Throws dimr::ParseError naming the file.
NpyArray ReadNpy(const std::string& path);
// All arrays of an .npz archive, by name without the ".npy" suffix.
std::map<std::string, NpyArray> ReadNpz(const std::string& path);
// Writes arrays as an uncompressed .npz (float64 for "f8", uint8 for "u1", int64 for "i8").
void WriteNpz(const std::string& path, const std::map<std::string, NpyArray>& arrays);

}  // namespace dimr::eval
