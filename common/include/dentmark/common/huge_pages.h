#pragma once
// Big jobs (a 9 M-triangle scan) touch hundreds of MB of fresh memory. On a VM every fresh
// 4 KB page is a fault (~3 ms per MB); 2 MB transparent huge pages cut that ~20-fold.
// Where the kernel gives them only on request (THP 'madvise', the usual default), glibc
// asks for them for its heap when its tunable glibc.malloc.hugetlb=1 is set, which it reads
// at start-up only. So the process re-executes itself once with the tunable added.

namespace dentmark {

// Call first in main (or from a static initialiser). Returns without doing anything when
// the tunable is already set, when DENTMARK_HUGEPAGES=0, or when re-executing fails (no
// /proc): the program then runs on small pages, only slower.
void reexec_with_huge_pages();

// Big scans are processed in stages that each allocate and free tens of MB. Keeps what
// one stage frees for the next (a fresh page costs a fault and zeroing; reused memory
// costs nothing): one heap for every thread (a worker's freed records go to the main
// thread's next stage), big blocks from the heap instead of their own mappings, and no
// trimming. Call in main before any thread starts.
void keep_freed_memory_for_reuse();

// Whether this process runs with glibc's huge-page tunable set (for reports).
bool huge_pages_requested();

}  // namespace dentmark
