// Software rendering of triangle meshes to PNG contact sheets (docs pictures, `dimr cad
// render`, `dimr bsp render`).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::tools {

struct RenderTile {
  geometry::TriangleMesh mesh;
  std::vector<geometry::Vec3> face_colors;  // per face (linear RGB in [0,1]); empty: `color`
  geometry::Vec3 color = geometry::Vec3(0.6, 0.65, 0.75);
  geometry::Vec3 scale = geometry::Vec3::Ones();  // applied to vertices (e.g. nominal size)
  std::string label;                              // drawn under the tile
};

// A stable colour for a name (part names, class names).
geometry::Vec3 NameColour(const std::string& name);
// Renders the tiles in a grid of `cols` columns, `tile` pixels each, and writes a PNG.
void RenderSheet(const std::vector<RenderTile>& tiles, int cols, int tile, const std::string& out);
// Writes 8-bit RGB pixels (row-major, top row first) as a PNG file.
void WritePng(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgb);

}  // namespace dimr::tools
