// Large buffers that are refilled every iteration (the recorder's training
// samples, their sort keys and sorted copy, the field's per-sample arrays)
// grow to tens of megabytes while a render's iterations grow.  Each growth
// is a fresh mapping the kernel fills one 4 KiB page fault at a time, and in
// a virtual machine a fault costs microseconds: on veach-ajar (--guiding
// --spp 64, 2 threads) ~160,000 faults, 7% of the profile.  Linux's
// transparent huge pages, where the system allows them on advice
// (/sys/kernel/mm/transparent_hugepage/enabled = madvise), serve a 2 MiB
// aligned range with one fault instead.  Advice only: contents and results
// are unchanged, and elsewhere it does nothing.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace theia {

// Below this a buffer holds no aligned 2 MiB range worth the advice.
inline constexpr size_t kHugePageAdviceMin = size_t(4) << 20;

// Advises [data, data + bytes) (its whole 4 KiB pages) for huge pages.
inline void advise_huge_pages(void* data, size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (bytes < kHugePageAdviceMin) return;
  constexpr uintptr_t kPage = 4096;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(data) + kPage - 1) & ~(kPage - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(data) + bytes) & ~(kPage - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)data, (void)bytes;
#endif
}

// v.reserve(n), with a new buffer advised before anything touches it (the
// elements kept are copied in after the advice, so they land on huge pages
// too).  No-op when the capacity is already there.
template <class Vector>
void reserve_huge(Vector& v, size_t n) {
  if (v.capacity() >= n) return;
  Vector grown;
  grown.reserve(n);
  advise_huge_pages(grown.data(), grown.capacity() * sizeof(typename Vector::value_type));
  grown.insert(grown.end(), v.begin(), v.end());
  v.swap(grown);
}

// push_back's doubling, through reserve_huge.
template <class Vector>
void grow_huge_for_one_more(Vector& v) {
  if (v.size() == v.capacity()) reserve_huge(v, std::max<size_t>(2 * v.capacity(), 1024));
}

}  // namespace theia
