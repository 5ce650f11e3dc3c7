// Torch-free entry points of the sparse-convolution benchmark (`dimr bench sparse`) and the
// procedural scanned-room generator it runs on.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace dimr::nn {

// Surface samples of a procedurally generated scanned room (floor, walls with a door gap,
// tables, chairs, cabinets/boxes), metres, z up, ~1 point per 2 cm voxel with scanner noise.
struct RoomCloud {
  std::vector<std::array<float, 3>> points;
  std::array<float, 3> size{0, 0, 0};  // room extent (x, y, wall height)
};

// Scales the room so that voxelising at 2 cm gives about target_voxels occupied voxels.
RoomCloud GenerateRoomCloud(int64_t target_voxels, uint64_t seed);
// Mean number of occupied 26-neighbours per occupied voxel at `voxel` metres.
double RoomMeanNeighbours(const RoomCloud& room, double voxel);
// Number of occupied voxels at `voxel` metres.
int64_t RoomVoxelCount(const RoomCloud& room, double voxel);

struct SparseBenchOptions {
  int64_t sites = 100000;                       // target active voxels of the room
  std::vector<int64_t> widths{16, 32, 64, 96};  // SubM3 C -> C layers to time
  int threads = 0;                              // at::set_num_threads; 0 = leave as is
  int repeats = 3;                              // timed runs per row (after one warm-up)
  bool torch_ops = true;                        // also time the torch-ops path
  bool unet = true;                             // time the stage-1 U-Net
  bool unet_backward = true;                    // ... and its forward + backward
  bool unet_torch_ops = false;  // also time the U-Net forward on the torch-ops path (slow)
  // Kernel paths of the fused rows: "auto" (the path in force), "avx512", "avx2", "gemm" or
  // "all" (every path this CPU supports); each fused row runs once per path.
  std::vector<std::string> kernels{"auto"};
  bool sgemm = true;  // measure one-thread sgemm (2048^3) for reference
  uint64_t seed = 1;
};

struct SparseBenchRow {
  std::string layer;    // e.g. "subm3 64->64", "unet stage1 forward (eval)"
  std::string backend;  // "fused" / "torch-ops"
  std::string kernels;  // fused: kernel path ("avx512", "avx2", "gemm"); torch-ops: "torch"
  int64_t width = 0;
  int64_t sites = 0;
  int64_t pairs = 0;       // rulebook pairs (conv rows) or 0
  double forward_ms = 0;   // median
  double backward_ms = 0;  // median, 0 if not measured
  double total_ms = 0;
  double gflops = 0;  // (forward + backward) useful GEMM FLOPs / total time
  // Process CPU time (all threads) of forward + backward: on a machine shared with other
  // processes the wall times above inflate, CPU time much less so.
  double cpu_ms = 0;
};

struct SparseBenchReport {
  std::vector<SparseBenchRow> rows;
  std::string cpu_model;        // /proc/cpuinfo model name, family and model
  std::string cpu_isa;          // vector ISA the CPU reports, e.g. "avx512f avx2 fma"
  std::string default_kernels;  // the kernel path a plain run takes
  double sgemm_gflops = 0;      // one-thread at::mm 2048 x 2048 x 2048, median of 3 (0: skipped)
  double sgemm_cpu_gflops =
      0;            // the same over process CPU time (less inflated on a loaded machine)
  int threads = 0;  // at::get_num_threads() during the run
  std::string parallel_info;
  int64_t room_points = 0;
  int64_t room_voxels = 0;
  double rulebook_ms = 0;        // SubM3 rulebook of the level-0 room voxels
  double peak_rss_mb = 0;        // VmHWM after the U-Net forward + backward
  double final_peak_rss_mb = 0;  // VmHWM at the end of the run
};

SparseBenchReport RunSparseBench(const SparseBenchOptions& options);

}  // namespace dimr::nn
