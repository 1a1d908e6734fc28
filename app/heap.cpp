// The heap's settings, linked into every executable that renders (theia and
// theia_bench: CMakeLists.txt, theia_heap), so that the bench measures the
// engine on the heap it ships with.
//
// jemalloc reads its options from this symbol at start-up: the heap on
// transparent huge pages.  A render's buffers (path pool, film copies,
// queues, Embree's BVH) are first touched page by page, and in a virtual
// machine each 4 KiB page fault traps to the hypervisor; 2 MiB pages make
// 1/512 as many faults and TLB misses.  Where the system offers huge pages
// only on request (/sys/kernel/mm/transparent_hugepage/enabled = madvise)
// jemalloc requests them; where it offers none, nothing changes.  Images are
// unchanged.
extern "C" {
const char* malloc_conf = "thp:always,metadata_thp:auto";
}
