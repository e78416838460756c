#pragma once

namespace skyfall {

// Training allocates and frees the same large buffers (renders, gradients,
// loss planes of a few MB each) at every step. With glibc's defaults each
// such buffer is a fresh mapping returned to the kernel on free, so every
// step pays page faults to map and zero it again (a large share of the
// photometric loss's time; decision D-031). This keeps freed heap memory
// for reuse: buffers up to 32 MiB come from the heap, and up to 256 MiB of
// freed heap stays with the process. Peak memory is unchanged (freed memory
// is reused before new memory is taken). Call once, at the start of main; a
// no-op without glibc.
void KeepFreedMemoryForReuse();

}  // namespace skyfall
