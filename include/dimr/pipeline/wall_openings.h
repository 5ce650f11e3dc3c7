// Structure prior for stage 1's labels, the complement of wall_planes.h: flat objects that sit
// *in* a wall plane - a closed door leaf, a window pane - are labelled wall by the network
// whatever their colour (docs/real.md "Where the v2 test gap is": 13 of 20 closed doors of 40
// SynthScan v2 test rooms; scene0470_00's window 85 % wall, its door 38 %; SynthScan pane
// rooms, `dimr synth --window-pane`: 71 % of the pane points). A region of the wall plane that
// is large and compact and differs from the wall around it becomes the object.
//
// Two ways to call a region, both measured (docs/real.md "Wall openings"):
//   - by the network's probabilities (`shape_class` false): the evidence is P(door) + P(window)
//     + P(curtain) + P(picture), the class their largest sum. Measured: it does not work - on
//     plain wall points the network already gives these classes ~0.25 together (missed door
//     points ~0.33, missed panes ~0.34 with P(window) only 0.04), so the regions are mostly
//     wall (v2 validation mIoU -0.02) and panes would take picture or curtain;
//   - by colour contrast / recess and shape (`shape_class` true, `seed_prob` 1, `weak_prob` 0:
//     the stage-1 card's setting since 2026-12-07): a region from the wall's foot that is tall
//     is a door, one above a sill and set back behind the wall's face a window.
//
// The rule, per wall plane of ApplyWallPlanes (its normal points into the room):
//   1. the points labelled wall in a band around the plane (`front` in front of it, `back`
//      behind it) and within its span are rasterised into `cell` x `cell` cells of the plane
//      (along it, up) - what the network missed, not the objects it found; a plane with fewer
//      than 1.5 points per occupied cell (4.5 cm voxel means) is rasterised at twice the edge;
//   2. per cell: the mean of P(door) + P(window) + P(curtain) + P(picture) over its points
//      ("opening probability"), its mean colour, its mean depth behind the plane;
//   3. the plane's wall colour is the median of the colours of cells on the plane that the
//      network takes for wall, its spread their median absolute deviation; a cell's colour
//      contrast is its largest per-channel robust z-score against it;
//   4. a cell is part of an opening when its opening probability reaches `seed_prob`, or
//      reaches `weak_prob` while its colour contrast reaches `contrast` or it lies `recess`
//      behind the plane;
//   5. a morphological opening by `erode` cells drops thin bands of such cells (the wall
//      around an object the network did label, whose points lean towards it); 8-connected
//      regions of the rest that cover >= `min_area`, whose bounding box is
//      >= `min_side` on both sides and filled to >= `min_fill`, take the class among door,
//      window, curtain and picture with the largest probability summed over the region's
//      points; their points whose own opening probability reaches `weak_prob` get that class
//      (a surely-wall point of a border cell stays). Nothing else changes.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/wall_planes.h"

namespace dimr::pipeline {

struct WallOpeningConfig {
  double cell = 0.05;       // m, raster in the plane
  double front = 0.05;      // m, band in front of the plane (room side)
  double back = 0.15;       // m, band behind it (recessed panes, leaves in their frames)
  double seed_prob = 0.25;  // opening probability that alone makes a cell part of an opening
  double weak_prob = 0.05;  // ... with colour contrast or recess
  double contrast = 3.0;    // robust z-score of a cell's colour against the wall's
  double recess = 0.03;     // m behind the plane
  double min_area = 0.3;    // m², smallest opening
  double min_side = 0.3;    // m, both sides of its bounding box
  double min_fill = 0.4;    // cells / bounding-box cells
  int erode = 2;            // cells: morphological opening of the opening cells
  // The class by shape instead of probability: a region from the wall's foot (within
  // `door_foot`) that is `door_height` tall or reaches the wall's top is a door, one whose
  // bottom is `window_sill` above the foot and that lies `window_recess` behind the wall's
  // face on average a window; others stay wall, and so does a region
  // whose mean depth is more than `max_proud` in front of the plane (it hangs on the wall).
  bool shape_class = false;
  double door_foot = 0.15, door_height = 1.5, window_sill = 0.3, max_proud = 0.01;
  double window_recess = 0.01;  // m: a window's mean depth behind the plane (glass is set back)
  void Validate() const;        // throws dimr::InvalidArgument naming the field
};

struct WallOpeningRegion {
  int rfs_class = -1;
  int plane = -1;          // index into WallPlaneResult::planes
  double area = 0;         // m² of cells
  double width = 0;        // m along the wall
  double height = 0;       // m
  double z_min = 0;        // m, lowest cell
  double probability = 0;  // mean P(rfs_class) over the region's points
  std::size_t points = 0;  // in the region
  std::size_t relabelled = 0;
};

struct WallOpeningResult {
  std::vector<WallOpeningRegion> regions;  // the ones that relabelled points
  std::size_t relabelled = 0;
};

// Relabels `semantic` (RFS classes, one per point) in place. `rows` holds the network's
// per-point class probabilities (after the class bias); `colours` (0..1, one per point) may be
// null: then only probability and recess count. Deterministic. Throws dimr::InvalidArgument
// for sizes that differ or a probability table that does not cover the points
// (nn::CheckPointRows).
WallOpeningResult ApplyWallOpenings(const std::vector<Eigen::Vector3f>& points,
                                    const std::vector<Eigen::Vector3f>* colours,
                                    const WallPlaneResult& walls, const nn::Stage1PointRows& rows,
                                    const WallOpeningConfig& config, std::vector<int>* semantic);

}  // namespace dimr::pipeline
