// Allocator settings for processes that run LibTorch: call once at start-up, before the first
// large allocation (the `dimr` command does it in main(); a node or another program should do
// the same).
//
// LibTorch allocates and frees tensors of megabytes on every layer call. glibc's defaults hand
// such blocks back to the kernel (mmap / trim), so every step page-faults them in again. On a
// 2-vCPU virtual machine page faults ran at ~220 MB/s: touching a fresh 268 MB block 50 times
// took 59 s, 1.2 s with the heap kept; a BSP fine-tune ran > 4x slower (43 % system time), and
// the stage-1 U-Net forward 10-15 % slower (docs/benchmarks.md). Both settings are needed:
// fixing only the trim threshold also pins the mmap threshold at 128 KB (4x slower).
#pragma once

namespace dimr {

enum class AllocatorTuning {
  kTuned,         // mmap threshold 1 GB (or glibc's 32 MB maximum), heap never trimmed
  kUserSettings,  // GLIBC_TUNABLES or DIMR_DEFAULT_MALLOC=1 set: glibc's behaviour kept
  kUnsupported,   // not glibc: nothing done
};

// Keeps freed tensor memory in the heap (glibc mallopt M_MMAP_THRESHOLD, M_TRIM_THRESHOLD)
// unless the environment asks for glibc's defaults (GLIBC_TUNABLES set, or
// DIMR_DEFAULT_MALLOC=1). Idempotent.
AllocatorTuning TuneAllocatorForTensors();

}  // namespace dimr
