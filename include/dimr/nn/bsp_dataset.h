// Training data of the BSP-CVAE shape autoencoder, independent of LibTorch: per shape the
// filled occupancy grid the encoder sees and pools of query points inside/outside the shape,
// in the network's normalised cube [-1, 1]^3 (canonical axes x forward, y left, z up; the
// unit-box CAD model scaled by 2 * (1 - 1/R) like the reference's per-axis normalisation).
// Stored on disk as a compact binary file (the cache `dimr bsp prepare` writes): grids
// bit-packed, point coordinates quantised to 16 bits over [-1, 1] (step 3.1e-5).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace dimr::nn {

struct BspSample {
  int cad_class = 0;                   // 0..num_classes-1
  std::string model_id;                // CAD model id (ShapeNet-style)
  std::vector<std::uint8_t> grid;      // R^3 encoder input (x fastest): 1 = cell touches the solid
  std::vector<std::uint8_t> iou_grid;  // R^3 target: 1 = the cell centre is inside the solid
  std::vector<float> inside_points;    // 3*K coordinates of points inside the shape
  std::vector<float> outside_points;   // 3*L coordinates of points outside the shape
};

struct BspDataset {
  int resolution = 32;  // R
  std::vector<BspSample> samples;

  // Binary file: magic "DIMRBSPD", version 2, R, count, then per sample the fields above.
  // Load checks every count against the file size and throws dimr::ParseError naming the
  // file and the sample on any inconsistency.
  void Save(const std::string& path) const;
  static BspDataset Load(const std::string& path);
  // Concatenates `other` (same resolution required).
  void Append(const BspDataset& other);
};

// The value a coordinate takes after a Save/Load round trip (16-bit quantisation).
float QuantizeBspCoordinate(float v);

}  // namespace dimr::nn
