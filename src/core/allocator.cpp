#include "dimr/core/allocator.h"

#include <cstdlib>
#include <cstring>

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace dimr {

AllocatorTuning TuneAllocatorForTensors() {
#ifdef __GLIBC__
  if (std::getenv("GLIBC_TUNABLES") != nullptr) return AllocatorTuning::kUserSettings;
  if (const char* v = std::getenv("DIMR_DEFAULT_MALLOC");
      v != nullptr && std::strcmp(v, "1") == 0) {
    return AllocatorTuning::kUserSettings;
  }
  // 1 GB: BSP training allocates 268 MB tensors (batch 32 x 2048 points x 1024 planes), which
  // glibc's 32 MB dynamic maximum still maps and unmaps on every step. Older glibc refuses
  // values above 32 MB; fall back to that.
  if (mallopt(M_MMAP_THRESHOLD, 1 << 30) == 0) mallopt(M_MMAP_THRESHOLD, 32 << 20);
  // Never trim: with a 1 GB threshold glibc still shrank the heap by brk when more than that
  // was free at once (a BSP training step frees ~1.5 GB), and re-faulted it on the next step.
  mallopt(M_TRIM_THRESHOLD, -1);
  return AllocatorTuning::kTuned;
#else
  return AllocatorTuning::kUnsupported;
#endif
}

}  // namespace dimr
