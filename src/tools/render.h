// Software rendering of triangle meshes to PNG contact sheets (docs pictures, `dimr cad
// render`, `dimr bsp render`).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/oriented_box.h"
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
// One panel of a perspective 3-D scene picture: input points (splats), meshes (two-sided
// shading: BSP and CAD windings are not guaranteed outward), box edges; a title above.
struct ScenePanel {
  std::vector<geometry::Vec3> points;
  std::vector<geometry::Vec3> point_colors;  // per point, [0,1]; empty: grey
  struct Mesh {
    geometry::TriangleMesh mesh;
    geometry::Vec3 color = geometry::Vec3(0.6, 0.65, 0.75);
  };
  std::vector<Mesh> meshes;
  struct Box {
    geometry::OrientedBox box;
    geometry::Vec3 color = geometry::Vec3(0.1, 0.1, 0.1);
  };
  std::vector<Box> boxes;
  std::string title;
};
// Renders the panels side by side, `width` x `height` pixels each, all seen by the same
// perspective camera (from above a corner of the bounds of every panel's points and meshes),
// and writes a PNG. Throws dimr::InvalidArgument for no panels, a size below 16 pixels or
// nothing to frame.
void RenderScenePanels(const std::vector<ScenePanel>& panels, int width, int height,
                       const std::string& out);
// Colour of instance / class `index` from a fixed 12-colour palette.
geometry::Vec3 PaletteColour(int index);

// Writes 8-bit RGB pixels (row-major, top row first) as a PNG file.
void WritePng(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgb);

}  // namespace dimr::tools
