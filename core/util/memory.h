#pragma once

// The process's memory, as the operating system sees it (Linux /proc), for limits that must stop a
// job with a clear message before the kernel's out-of-memory killer stops it without one.

#include <cstdint>

namespace saker {

// Resident set size of this process, bytes; 0 when unknown (no /proc).
int64_t ResidentMemoryBytes();

// Peak resident set size of this process so far (VmHWM), bytes; 0 when unknown.
int64_t PeakResidentMemoryBytes();

// Physical memory of the machine (MemTotal), bytes; 0 when unknown.
int64_t PhysicalMemoryBytes();

// The default limit for processing memory: three quarters of the physical memory, in MiB (0 when
// the physical memory is unknown: no limit).
int64_t DefaultMemoryLimitMiB();

}  // namespace saker
