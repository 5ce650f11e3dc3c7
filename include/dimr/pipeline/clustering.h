// Stage-1 clustering (dimr-method.md section 3): PointGroup's ball query + BFS on the CAD
// points, single-scale (training, 3.4) or multi-scale (test, 3.5), greedy point-set-IoU NMS
// (3.6) and the proposal heading vote (2.4, section 15 fact 3). LibTorch-free.
//
// Ball query and BFS follow the reference ops exactly: neighbours of j are the points k with
// label[k] >= 0 (the reference queries the CAD points only) and |x_j - x_k|^2 < r^2 (strict,
// float arithmetic as in the CUDA kernel), j itself included, taken in increasing index order
// and truncated after max_neighbours hits. BFS visits seeds in index order and follows an
// edge j -> k only if label[k] == label[j]; visited points are never revisited (also those of
// a cluster that is then dropped for being too small). The query runs on a uniform voxel hash
// (cell = radius), so a pass is O(N * density), not O(N^2); see clustering.cpp (BallQuery)
// for how it avoids the reference's full neighbour scans while giving the same clusters.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

namespace dimr::pipeline {

struct ClusterPass {
  bool shifted = false;  // cluster points + predicted offsets instead of the raw points
  double radius = 0.03;  // ball-query radius, metres (> 0)
};

struct ClusteringConfig {
  // Test-time multi-scale clustering of the reference (section 3.5), in this order.
  std::vector<ClusterPass> passes{{false, 0.03}, {true, 0.01}, {true, 0.03}, {true, 0.05}};
  int min_points = 10;        // clusters with fewer points are dropped (>= keeps)
  int max_neighbours = 1000;  // ball-query cap, neighbours scanned in index order (section 3.2)
  // false: approximate mode, no cap (each pass is RadiusComponents): where no point has more
  // than max_neighbours labelled points within the radius the clusters are the exact ones as
  // sets (points in index order instead of BFS order); where some have, dense blobs are not
  // fragmented by the cap (larger clusters). 3-8x faster on the card's dense shifted passes;
  // docs/benchmarks.md has the speed and the unchanged test-room / real-room metrics.
  bool neighbour_cap = true;

  // Throws dimr::InvalidArgument naming the bad field (passes empty, a radius not finite or
  // <= 0, min_points < 1, max_neighbours < 1).
  void Validate() const;
  // Single scale for training (section 3.4): original r = 0.03, then shifted r = 0.03.
  static ClusteringConfig Training();
};

// BFS clustering of one pass (section 3.3). Points with label < 0 are skipped (neither seeds
// nor neighbours). Clusters come in seed order, each cluster's point indices in BFS visiting
// order (neighbours of a popped point are pushed in increasing index order). Clusters with
// fewer than min_points points are dropped. Throws dimr::InvalidArgument if the sizes differ,
// a coordinate of a labelled point is not finite or more than 1e15 radii from the origin,
// radius is not finite or <= 0, min_points < 1 or max_neighbours < 1. Cost: where the cap
// cannot bind, the unvisited same-label points around each popped point; where it can, also
// the hits below the first candidate whose rank is not settled by per-sub-box bounds.
std::vector<std::vector<int>> BfsClusters(const std::vector<Eigen::Vector3f>& points,
                                          const std::vector<int>& labels, double radius,
                                          int min_points, int max_neighbours = 1000);

// The clusters of BfsClusters without the neighbour cap (max_neighbours infinite) as sets:
// the connected components of the graph linking labelled points of equal labels with
// |x_j - x_k|^2 < r^2 (float, strict), with at least min_points points, each in increasing
// index order, ordered by their smallest index (BfsClusters' seed order). Union-find over
// half-cell parts (whose points are all within r of each other) with box tests deciding most
// pairs of parts: ~O(N) on dense blobs, no per-query scans. Throws as BfsClusters.
std::vector<std::vector<int>> RadiusComponents(const std::vector<Eigen::Vector3f>& points,
                                               const std::vector<int>& labels, double radius,
                                               int min_points);

// The SIMD path of BfsClusters' distance tests: "avx2" (8 at a time) where the CPU has AVX2
// and it is allowed, else "sse2" (4 at a time). Every path performs the same float operations
// (no FMA), so the clusters are identical.
const char* ClusteringSimdPath();
// Allows (default) or forbids the AVX2 path, e.g. to test or time the SSE2 one on an AVX2
// machine; returns the previous setting. Not thread-safe: call it before clustering starts.
bool SetClusteringAvx2(bool enabled);

struct Proposal {
  std::vector<int> points;  // point indices (BFS order), unique
  int label = -1;           // the (common) label of its points
  double score = 0;         // filled by the caller (stage 1: semantic score; stage 2: network)
  int pass = 0;             // index of the ClusteringConfig pass that produced it
};

// All passes of `config` concatenated in pass order (shifted passes cluster points + offsets).
// Throws dimr::InvalidArgument on size mismatches or an invalid config.
std::vector<Proposal> MultiScaleClusters(const std::vector<Eigen::Vector3f>& points,
                                         const std::vector<Eigen::Vector3f>& offsets,
                                         const std::vector<int>& labels,
                                         const ClusteringConfig& config);

// Point-set IoU |A n B| / (|A| + |B| - |A n B|) of two proposals' point lists (unique
// indices); 0 if both are empty.
double PointIou(const std::vector<int>& a, const std::vector<int>& b);

// Greedy class-agnostic NMS on point-set IoU (section 3.6): proposals sorted by score
// descending (stable: equal scores keep their input order), keep the best, drop every
// remaining proposal with IoU > iou_threshold, repeat. Returns the kept indices in score
// order. Intersections are counted through a per-point inverted index: the cost is the sum
// over kept proposals of the number of (point, proposal) incidences of their points, not
// O(P^2 N). Throws dimr::InvalidArgument for a negative point index, a non-finite score or a
// NaN threshold.
std::vector<int> PointIouNms(const std::vector<Proposal>& proposals, double iou_threshold);

// Proposal heading (section 15 fact 3): k = argmax over the mean of the points' 12 bin
// probabilities (first maximum on ties), plus the mean normalised residual of bin k times
// pi/12, added to the bin centre k * pi/6; wrapped to (-pi, pi]. heading_prob and
// heading_residual are R x 12 row-major arrays; point i's row is point_row[i] (per-voxel rows,
// nn::Stage1PointRows) or i when point_row is empty. Throws dimr::InvalidArgument if `points`
// is empty, an array's size is not a multiple of 12, the two differ, or an index or row is out
// of range.
double ProposalHeading(const std::vector<int>& points, const std::vector<float>& heading_prob,
                       const std::vector<float>& heading_residual,
                       const std::vector<std::int64_t>& point_row = {});

// (Heading codes themselves: nn::EncodeHeading / nn::DecodeHeading, dimr/nn/stage1_data.h.)

}  // namespace dimr::pipeline
