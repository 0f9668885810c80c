#pragma once
// Big jobs (a 9 M-triangle scan) touch a hundred MB or more of fresh memory, in stages
// that each allocate and free tens of MB. On a VM a fresh page is a costly fault; reused
// memory costs nothing. So the heap is set up once, first thing in main, to keep what one
// stage frees for the next: one heap for every thread (a worker's freed records go to the
// main thread's next stage), big blocks from the heap instead of their own mappings, and
// no trimming.
//
// Transparent huge pages only on request (DENTMARK_HUGEPAGES=1): then the first GiB of
// the heap is reserved as address space and marked for them (madvise). They cut the
// fault count 512-fold, but on a VM whose host takes back the memory its guest frees
// (free page reporting, as on Firecracker) they are the slow kind. The guest hands back
// whole free 2 MB blocks a few seconds after they are freed, and a fresh huge page is
// made of such a block: faulting it in costs ~3 ms per MB, while small pages come first
// from the fragments the host still backs (~0.4 ms per MB). Measured on the 9 M-triangle
// door run 5 s after the last run: 0.71 s with huge pages, 0.44 s without. Straight after
// a run that freed huge pages they win by ~0.04 s, and a probe of the first few free
// blocks could not tell the two cases apart (the first blocks were backed, the rest not).

#include <cstddef>

namespace dentmark {

// Call first in main, before any thread starts. Returns whether huge pages were asked
// for (never under AddressSanitizer, which has its own heap).
bool prepare_heap_for_big_jobs();

// Whether prepare_heap_for_big_jobs asked for huge pages (for reports).
bool huge_pages_requested();

// Anonymous memory of this process now backed by huge pages (bytes; 0 if unknown).
std::size_t huge_page_bytes_in_use();

}  // namespace dentmark
