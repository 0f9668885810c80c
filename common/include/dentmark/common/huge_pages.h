#pragma once
// Big jobs (a 9 M-triangle scan) touch a hundred MB or more of fresh memory, in stages
// that each allocate and free tens of MB. On a VM every fresh 4 KB page is a costly fault
// (~3 ms per MB); reused memory costs nothing, and 2 MB transparent huge pages cut the
// fault count 512-fold. So the heap is set up once, first thing in main:
//  * what one stage frees is kept for the next: one heap for every thread (a worker's
//    freed records go to the main thread's next stage), big blocks from the heap instead
//    of their own mappings, and no trimming;
//  * the first GiB of the heap is reserved as address space (nothing is touched) and
//    marked for transparent huge pages (madvise), which the kernel's usual THP setting
//    ('madvise') gives only on request. DENTMARK_HUGEPAGES=0 leaves this out.

#include <cstddef>

namespace dentmark {

// Call first in main, before any thread starts. Returns whether huge pages were asked
// for (not under AddressSanitizer, which has its own heap).
bool prepare_heap_for_big_jobs();

// Whether prepare_heap_for_big_jobs asked for huge pages (for reports).
bool huge_pages_requested();

// Anonymous memory of this process now backed by huge pages (bytes; 0 if unknown).
std::size_t huge_page_bytes_in_use();

}  // namespace dentmark
