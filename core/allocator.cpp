#include "core/allocator.h"

#include <cstdlib>  // defines __GLIBC__ with glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace skyfall {

void KeepFreedMemoryForReuse() {
#if defined(__GLIBC__)
  constexpr int kMmapThresholdBytes = 32 << 20;  // glibc's largest allowed on 64-bit
  constexpr int kTrimThresholdBytes = 256 << 20;
  mallopt(M_MMAP_THRESHOLD, kMmapThresholdBytes);
  mallopt(M_TRIM_THRESHOLD, kTrimThresholdBytes);
#endif
}

}  // namespace skyfall
